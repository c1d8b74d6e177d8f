"""``brdffit models [NAME]``: the model registry, with each model's parameters."""

from __future__ import annotations

import json

from .._columns import columns


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "models",
        parents=parents,
        allow_abbrev=False,
        help="list the registered models, or one model's parameters",
        description="Without NAME: every registered model with a one-line description. With "
        "NAME: that model's parameters (shape, bounds, default, log-space fitting) and source.",
    )
    p.add_argument("name", nargs="?", metavar="NAME", help="a model name, e.g. ggx")
    p.add_argument("--json", action="store_true", help="print as JSON on stdout")
    p.set_defaults(run=run, needs_jax=False)


def _param_dict(param) -> dict:
    default = param.default_array().tolist()
    return {"name": param.name, "shape": list(param.shape), "lower": param.lower,
            "upper": param.upper, "default": default, "log": param.log,
            "description": param.description}


def model_dict(model) -> dict:
    return {"name": model.name, "description": model.description, "isotropic": model.isotropic,
            "reference": model.reference, "params": [_param_dict(p) for p in model.params]}


def _default_text(value) -> str:
    if isinstance(value, list):
        return ",".join(f"{v:g}" for v in value) if len(set(value)) > 1 else f"{value[0]:g}"
    return f"{value:g}"


def format_model(d: dict) -> str:
    lines = [f"{d['name']}: {d['description']}"]
    if d["reference"]:
        lines.append(f"  reference: {d['reference']}")
    lines.append(f"  isotropic: {'yes' if d['isotropic'] else 'no'}")
    rows = [("parameter", "shape", "bounds", "default", "description")]
    for p in d["params"]:
        shape = "rgb" if p["shape"] == [3] else ("scalar" if not p["shape"] else str(p["shape"]))
        bounds = f"[{p['lower']:g}, {p['upper']:g}]" + (" log" if p["log"] else "")
        rows.append((p["name"], shape, bounds, _default_text(p["default"]), p["description"]))
    return "\n".join(lines + columns(rows, "<<<<<", indent="  "))


def run(args) -> int:
    from .. import available_models, get_model

    if args.name:
        d = model_dict(get_model(args.name))
        print(json.dumps(d, indent=2) if args.json else format_model(d))
        return 0
    models = [get_model(n) for n in available_models()]
    if args.json:
        print(json.dumps([model_dict(m) for m in models], indent=2))
        return 0
    print("\n".join(columns([(m.name, f"{len(m.params)} params ({m.size} values)",
                               m.description) for m in models], "<<<")))
    print("\n`brdffit models NAME` shows a model's parameters, bounds and defaults.")
    return 0
