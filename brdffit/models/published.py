"""Published fits as parameters of registered models: one entry per bbm model class.

A line of a ``.fit`` file (:mod:`data_formats.published`) names bbm's class of the specular
model (``NganCookTorrance``, ``LowSmooth``, ``Bagher`` …) and its parameters in bbm's names and
conventions. A :class:`PublishedForm` says which registered model means the same function and
how the line's numbers become that model's parameters, so that a published fit can be
evaluated, plotted, exported, scored and compared like a fit of brdffit's own. The modules
that register the literature's models register their forms beside them
(:func:`register_published`); :func:`published_params` turns a line into ``(model, params)``.

A form is right when the model, evaluated with the converted parameters, reproduces bbm's own
reference values for every line of the published file (``tests/test_published_models.py``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from data_formats.published import PublishedFit

from ..errors import UnknownNameError
from .registry import Model, get_model


@dataclasses.dataclass(frozen=True)
class PublishedForm:
    """How one bbm model class maps onto a registered model.

    Attributes:
        bbm_class: the class name in the ``.fit`` line (``NganCookTorrance``).
        model: the registered model's name.
        to_params: ``fit -> {name: value}``: the parameters of ``model`` (all of them) that
            reproduce the published line, its Lambertian albedo included.
        study: the publication, for tables (``"Ngan 2005"``, ``"Löw 2012"``, ``"Bagher 2012"``).
    """

    bbm_class: str
    model: str
    to_params: Callable[[PublishedFit], dict] = dataclasses.field(repr=False)
    study: str = ""


_FORMS: dict[str, PublishedForm] = {}


def register_published(form: PublishedForm) -> PublishedForm:
    """Add ``form`` under its bbm class name (unique)."""
    if form.bbm_class in _FORMS:
        raise ValueError(f"a published form for {form.bbm_class!r} is already registered")
    _FORMS[form.bbm_class] = form
    return form


def published_form(bbm_class: str) -> PublishedForm:
    try:
        return _FORMS[bbm_class]
    except KeyError:
        raise UnknownNameError("published model", bbm_class, _FORMS) from None


def published_forms() -> dict[str, PublishedForm]:
    """Every registered form, by bbm class name (a copy)."""
    return dict(_FORMS)


def published_params(fit: PublishedFit) -> tuple[Model, dict[str, np.ndarray]]:
    """The registered model and its parameters that mean the published line ``fit``."""
    form = published_form(fit.model)
    model = get_model(form.model)
    params = form.to_params(fit)
    missing = set(model.names) - set(params)
    if missing:
        raise ValueError(f"published form {form.bbm_class!r} leaves {sorted(missing)} of model "
                         f"{model.name!r} unset")
    return model, {k: model.param(k).coerce(v) for k, v in params.items()}
