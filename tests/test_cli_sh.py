"""The SH commands: sh (Figure 2 through the command line), irradiance, error, export, design."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import shared
from lightprobe.envmap import read_envmap
from lightprobe.export import TARGETS
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
    assert all(r["paper_mean"] >= 0 for r in rows)


@pytest.mark.parametrize("target", TARGETS)
def test_export_command(tmp_path, capsys, target):
    out = tmp_path / f"probe.{'cs' if target == 'unity' else 'txt'}"
    code, _, _ = run(capsys, "export", "--to", target, "-o", out)
    assert code == 0 and out.stat().st_size > 100


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
