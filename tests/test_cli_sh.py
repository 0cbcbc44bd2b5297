"""The SH commands: sh (Figure 2 through the command line), irradiance, error, export, design."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import shared
from lightprobe.maps import read_envmap
from lightprobe.maps.images import write_image
from lightprobe.maps.layouts import LATLONG
from test_export import EVALUATORS
from test_cli import assert_clean_failure, run


def test_sh_json_reproduces_figure2_for_grace(capsys):
    code, out, _ = run(capsys, "sh", shared("debevec/angular/grace_probe.hdr"), "--frame", "rh2001", "--json")
    data = json.loads(out)  # one JSON object
    coeffs = np.array(data["coefficients"])
    assert code == 0 and coeffs.shape == (9, 3) and data["frame"] == "rh2001"
    ref = np.array(json.loads(shared("paper_tables/rh2001_figure2.json").read_text())["probes"]["grace"]["rgb"])
    scale = (coeffs * ref).sum() / (coeffs**2).sum()
    assert np.abs(scale * coeffs - ref).max() < 0.01


def test_sh_formats_and_orders(tmp_path, capsys):
    code, out, _ = run(capsys, "sh", "--order", 4, "--format", "csv")
    lines = out.strip().splitlines()
    assert code == 0 and lines[0] == "name,l,m,R,G,B" and len(lines) == 26 and lines[2].startswith("L1-1,1,-1,")
    code, _, _ = run(capsys, "sh", "--format", "npy", "-o", tmp_path / "c.npy", "--order", 3)
    assert code == 0 and np.load(tmp_path / "c.npy").shape == (16, 3)
    code, _, err = run(capsys, "sh", "--format", "npy")
    assert_clean_failure(code, err, "--output")


def test_irradiance_command_sh_and_brute_agree(tmp_path, capsys):
    for method in ("sh", "brute"):
        code, _, _ = run(capsys, "irradiance", "-o", tmp_path / f"{method}.exr", "--size", "32x16",
                         "--method", method, "--order", 6)
        assert code == 0
    sh, brute = read_envmap(tmp_path / "sh.exr"), read_envmap(tmp_path / "brute.exr")
    assert sh.grid == (16, 32)
    assert np.abs(sh.data - brute.data).mean() < 0.05 * brute.data.mean()


@pytest.mark.parametrize("size,layout", [("63x32", "latlong"), ("abc", "latlong"), ("0", "cube")])
def test_irradiance_size_errors(tmp_path, capsys, size, layout):
    code, _, err = run(capsys, "irradiance", "-o", tmp_path / "x.exr", "--size", size, "--layout", layout)
    assert_clean_failure(code, err, "--size")
    assert not (tmp_path / "x.exr").exists()


def test_error_command_json(capsys):
    code, out, _ = run(capsys, "error", "--order", "2,4", "--window", "all", "--normals", 200, "--json")
    rows = json.loads(out)
    assert code == 0 and len(rows) == 8
    assert {r["window"].split("(")[0].split(":")[0] for r in rows} == {"none", "hanning", "lanczos", "auto"}


def test_error_command_against_the_analytic_error(tmp_path, capsys):
    """L(d) = 1 + a·d_z: E(n) = π + (2π/3) a n_z exactly, so order 0 misses (2π/3)|a n_z| and, with ∫L dω = 4π,
    the paper's measure is |a| |n_z| / 6: mean |a|/12 over uniform normals, max |a|/6; order ≥ 1 is exact."""
    a = 0.5
    d = LATLONG.directions(LATLONG.grid_shape(256))
    write_image(tmp_path / "tilt.exr", (1 + a * d[..., 2:3]) * np.ones(3, np.float32))
    code, out, _ = run(capsys, "error", tmp_path / "tilt.exr", "--order", "0,1,2", "--window", "none",
                       "--normals", 4000, "--json")
    rows = {r["l_max"]: r for r in json.loads(out)}
    assert code == 0
    assert rows[0]["paper_mean"] == pytest.approx(a / 12, rel=2e-3)
    assert rows[0]["paper_max"] == pytest.approx(a / 6, rel=2e-3)
    for l in (1, 2):
        assert rows[l]["paper_max"] < 2e-4 and rows[l]["relative_max"] < 1e-3


@pytest.mark.parametrize("target", list(EVALUATORS))
def test_export_command(tmp_path, capsys, target):
    """Each file the command writes for a white furnace (a uniform map of radiance 1), read by the engine's own
    formula written in test_export.py: a white Lambertian surface shows E/π = 1 for every normal."""
    evaluate, options = EVALUATORS[target]
    white = write_image(tmp_path / "white.exr", np.ones((64, 128, 3), np.float32))
    out = tmp_path / f"probe.{'cs' if target == 'unity' else 'txt'}"
    extra = (["--gltf-scaling", options["gltf_scaling"]] if "gltf_scaling" in options else []) + (
        ["--frame", options["frame"]] if "frame" in options else [])
    code, _, _ = run(capsys, "export", white, "--to", target.split("-")[0], "-o", out, *extra)
    assert code == 0
    np.testing.assert_allclose(evaluate(out.read_text()), 1.0, rtol=3e-4)


def test_design_command(tmp_path, capsys):
    code, _, _ = run(capsys, "design", "-o", tmp_path / "d.png", "--set", "L1-1=-0.4", "--scale-band", "2=0.5",
                     "--json", tmp_path / "d.json", "--size", 32)
    assert code == 0 and (tmp_path / "d.png").stat().st_size > 1000
    edited = json.loads((tmp_path / "d.json").read_text())["coefficients"]
    np.testing.assert_allclose(edited[1], [-0.4, -0.4, -0.4], rtol=1e-12)  # stated in world, round-tripped
    for bad in (["--set", "L5-9=1"], ["--set", "nonsense"], ["--scale-band", "x"], ["--set", "L3-1=1"]):
        code, _, err = run(capsys, "design", "-o", tmp_path / "e.png", *bad)
        assert_clean_failure(code, err)
        assert not (tmp_path / "e.png").exists()
