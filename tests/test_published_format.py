"""The ``.fit`` reader: every published line parses, with :mod:`ast` only; bad lines are named."""

from __future__ import annotations

import numpy as np
import pytest

import published
from data_formats.published import (
    PublishedFitFormatError, parse_fit_line, read_fit_file, read_reference_values,
)


@pytest.mark.parametrize("stem", published.STEMS)
def test_every_published_file_parses_and_matches_its_reference_values(stem):
    fits, ref = published.load(stem)
    assert len(fits) >= 10 and ref.f.shape == (len(fits), len(ref.wi), 3)
    for fit in fits:
        assert fit.albedo.shape == (3,) and np.all(fit.albedo >= 0)
        assert fit.model and fit.params
        assert ref.of(fit.material).shape == (len(ref.wi), 3)
    np.testing.assert_allclose(np.linalg.norm(ref.wi, axis=1), 1.0, atol=1e-12)


def test_a_line_reads_into_names_and_numbers():
    fit = parse_fit_line("blue-acrylic = Aggregate(Lambertian(albedo = [0.0143, 0.033, 0.0639]), "
                         "NganCookTorrance(albedo = [0.0291, 0.0193, 0.0118], eta = 0.117, "
                         "roughness = -1.5e-2))", "x.fit:3")
    assert fit.material == "blue-acrylic" and fit.model == "NganCookTorrance"
    np.testing.assert_array_equal(fit.albedo, [0.0143, 0.033, 0.0639])
    assert fit.params["eta"] == 0.117 and fit.params["roughness"] == -0.015
    assert fit.source == "x.fit:3"
    assert parse_fit_line("  # a comment") is None and parse_fit_line("   ") is None


@pytest.mark.parametrize("line, needle", [
    ("m = __import__('os').system('true')", "expected Aggregate"),
    ("m = Aggregate(Lambertian(albedo = [1, 2, 3]), M(x = __import__('os')))",
     "is not a number"),
    ("m = Aggregate(Lambertian(albedo = [1, 2, 3]), M(x = 'text'))", "is not a number"),
    ("m = Aggregate(Lambertian(albedo = [1, 2, 3]), M(x = 1, x = 2))", "repeated"),
    ("m = Aggregate(Lambertian(albedo = [1, 2, 3]), M(1.0))", "keyword arguments only"),
    ("m = Aggregate(Lambertian(albedo = [1, 2]), M(x = 1))", "albedo = [r, g, b]"),
    ("m = Aggregate(Phong(albedo = [1, 2, 3]), M(x = 1))", "expected Lambertian"),
    ("m = Aggregate(Lambertian(albedo = [1, 2, 3]), M(x = 1e999))", "not finite"),
    ("m = Aggregate(Lambertian(albedo = [1, 2, 3]), M(x = [1, [2]]))", "is not a number"),
    ("m = Aggregate(Lambertian(albedo = [1, 2, 3]), M(x = (1,)", "not a fit expression"),
    ("no equals sign here", "expected 'material = Aggregate(...)'"),
])
def test_bad_lines_are_refused_with_their_place(line, needle):
    with pytest.raises(PublishedFitFormatError, match="x.fit:7") as info:
        parse_fit_line(line, "x.fit:7")
    assert needle in str(info.value)


def test_files_that_are_not_fit_files(tmp_path):
    (tmp_path / "empty.fit").write_text("# only a comment\n")
    with pytest.raises(PublishedFitFormatError, match="no fit lines"):
        read_fit_file(tmp_path / "empty.fit")
    (tmp_path / "bin.fit").write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(PublishedFitFormatError, match="not UTF-8"):
        read_fit_file(tmp_path / "bin.fit")
    line = "m = Aggregate(Lambertian(albedo = [1, 2, 3]), M(x = 1))\n"
    (tmp_path / "twice.fit").write_text(line + line)
    with pytest.raises(PublishedFitFormatError, match=r"twice.fit:2: material 'm' appears twice"):
        read_fit_file(tmp_path / "twice.fit")
    np.savez(tmp_path / "v.npz", materials=np.array(["m"]), wi=np.zeros((4, 3)))
    with pytest.raises(PublishedFitFormatError, match="no array"):
        read_reference_values(tmp_path / "v.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(PublishedFitFormatError, match="not a reference-value archive"):
        read_reference_values(tmp_path / "junk.npz")
