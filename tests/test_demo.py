"""``lightprobe demo`` run once, as a user runs it, on the shipped probe: every section's pictures, and the Bake
section — the bake of the probe for every engine in the report, its files linked inside the report, and each
engine's spheres from our bake beside its own. (Failures and refusals of the demo are tested in test_cli and
test_hardening.)"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from lightprobe.maps import EnvMap
from lightprobe.maps.layouts import LATLONG
from lightprobe.util.names import BAKE_ENGINES


def small_probe() -> EnvMap:
    """A 64×32 sky with one smooth bright spot: the section's work without the shipped probe's size."""
    d = LATLONG.directions(LATLONG.grid_shape(32))
    s = np.array([0.6, 0.5, -0.62]) / np.linalg.norm([0.6, 0.5, -0.62])
    spot = np.exp(-(np.degrees(np.arccos(np.clip(d @ s, -1, 1))) / 10.0) ** 2)
    return EnvMap((0.1 + 20 * spot[..., None] * np.array([1.0, 0.9, 0.8])).astype(np.float32), LATLONG)


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> tuple[Path, str]:
    """The whole demo, through the command line, once for this module's tests."""
    from lightprobe.cli import main

    root = tmp_path_factory.mktemp("demo") / "report"
    assert main(["demo", "--out", str(root)]) == 0
    return root, (root / "index.html").read_text()


# both tests read the one report: xdist keeps them on one worker
pytestmark = pytest.mark.xdist_group("demo")


def test_demo_writes_a_report_with_pictures(report):
    root, index = report
    for name in ("latlong", "angular", "sphere", "cube", "cross", "hcross"):
        assert f"layout_{name}.png" in index and (root / f"layout_{name}.png").stat().st_size > 1000
    assert "∫L dω" in index
    assert "peak resident memory of lightprobe convert" in index  # measured in a fresh process
    assert "energy_latlong_angular_rim.png" in index  # a sun in every pixel round the angular map's rim direction
    assert "render_reference.png" in index and "Mitsuba 3." in index  # the ground truth is there, not excused
    assert (root / "render_reference.png").stat().st_size > 1000
    for name in ("engine_three_ours_front", "engine_three_own_front", "engine_babylon_ours_toward",
                 "engine_babylon_own_toward", "engine_babylon_own_away", "engine_babylon_own_diffuse",
                 "engine_babylon_glb_diffuse"):  # spheres drawn by three.js and Babylon.js themselves
        assert f"{name}.png" in index and (root / f"{name}.png").stat().st_size > 1000
    assert "Babylon.js 9.35 (Node, default SH path)" in index
    glossy = ["glossy_sources", "glossy_synthesised", "glossy_direct"]
    for obj in ("sphere", "teapot", "bunny"):  # the teapot and bunny from ../shared/data, which the tests have
        glossy += [f"glossy_{obj}_conductorgold_reference", f"glossy_{obj}_conductorgold_rsibr_per-pixel-view",
                   f"glossy_{obj}_conductorgold_splitsum", f"glossy_{obj}_plastic_reference",
                   f"glossy_{obj}_plastic_rsibr"]
    for name in glossy:  # the glossy section
        assert f"{name}.png" in index and (root / f"{name}.png").stat().st_size > 500


def bake_report(tmp_path, monkeypatch) -> tuple[Path, str]:
    import lightprobe.report.demo as demo

    monkeypatch.setattr(demo, "SECTIONS", [demo.section_bake])
    monkeypatch.setattr(demo, "warm_up", lambda: 0.0)  # the bake loads the kernels it needs
    index = demo.run_demo(small_probe(), tmp_path / "report")
    return index.parent, index.read_text()


def links(root: Path, page: str) -> list[Path]:
    """Every href and src of the page, resolved against the report's folder."""
    return [(root / target).resolve() for target in re.findall(r'(?:href|src)="([^"#]+)"', page)]


def test_the_bake_section_links_every_engines_files_inside_the_report(report):
    from lightprobe_engines.runtimes import missing_engines

    root, page = report
    assert "<h2>Bake</h2>" in page
    targets = links(root, page)
    for engine in BAKE_ENGINES:
        assert f'href="bake/{engine}/manifest.json"' in page and f'href="bake/{engine}/USAGE.md"' in page
    # every link and picture is a file (or the bake folder) inside the report: the report is self-contained
    assert targets and all(t.is_relative_to(root.resolve()) and t.exists() for t in targets), targets
    files = [t for t in targets if t.is_file() and "bake" in t.parts]
    assert {t.parent.name for t in files} == set(BAKE_ENGINES)
    assert sum(t.stat().st_size for t in files) < 3_000_000  # a small bake: the report stays small
    if missing_engines():
        pytest.fail(f"the engine tests need {', '.join(missing_engines())}: run 'bash setup.sh --test'",
                    pytrace=False)
    # the engines drew our bake and their own: a picture per engine, two where the engine has its own prefilter
    for engine in ("threejs", "babylon", "gltf", "playcanvas", "filament"):
        assert f'src="bake_{engine}_ours.png"' in page
        assert (engine == "filament") != (f'src="bake_{engine}_own.png"' in page)
    from PIL import Image

    for name in ("bake_threejs_ours", "bake_threejs_own", "bake_playcanvas_ours", "bake_filament_ours"):
        image = np.asarray(Image.open(root / f"{name}.png").convert("L"), np.float64)
        assert image.shape == (64, 5 * 64)
        # five lit spheres on black: each sphere's square has a lit disc, its corners dark
        for k in range(5):
            square = image[:, 64 * k:64 * (k + 1)]
            assert square[24:40, 24:40].mean() > 5 and square[:6, :6].mean() < square[24:40, 24:40].mean(), (name, k)


def test_without_the_engines_the_section_says_so_in_one_line(tmp_path, monkeypatch):
    import lightprobe.report.bake as section

    monkeypatch.setattr(section, "engines_missing", lambda: ["node"])
    monkeypatch.setattr("lightprobe.util.names.BAKE_ENGINES", ("threejs",))  # one engine's bake shows the line
    root, page = bake_report(tmp_path, monkeypatch)
    assert page.count("Not drawn here: the engines need node") == 1
    assert "bake_threejs_ours.png" not in page and not list(root.glob("bake_*.png"))
    assert (root / "bake" / "threejs" / "environment.ktx2").is_file()
