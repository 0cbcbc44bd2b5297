"""Copy the three.js modules the viewer's page imports into the lightprobe package, from the npm version pinned in
engines/package-lock.json, so an installed lightprobe serves them itself (never committed: made at build time).

    python engines/vendor_three.py DEST     DEST: the package's viewer/vendor/three folder (setup.sh, setup.py)

Runs ``npm ci`` in engines/ first when node_modules lacks the pinned three. The copy is made aside and renamed into
place, and a VERSION file names the version it was made from, so a changed pin makes it again."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

ENGINES = Path(__file__).resolve().parent
SOURCE = ENGINES.parent / "src"


def pinned_version() -> str:
    lock = json.loads((ENGINES / "package-lock.json").read_text())
    return lock["packages"]["node_modules/three"]["version"]


def _installed(root: Path) -> str | None:
    try:
        return json.loads((root / "package.json").read_text())["version"]
    except (OSError, ValueError, KeyError):
        return None


def vendor_three(dest: Path) -> Path:
    """Fill ``dest`` with the page's three.js modules (and three's licence); returns ``dest``."""
    dest = Path(dest)
    version = pinned_version()
    if (dest / "VERSION").is_file() and (dest / "VERSION").read_text().strip() == version:
        return dest
    root = ENGINES / "node_modules" / "three"
    if _installed(root) != version:
        if shutil.which("npm") is None:
            raise SystemExit(f"vendor_three: three.js {version} is not in engines/node_modules and npm is missing")
        subprocess.run(["npm", "ci", "--no-audit", "--no-fund", "--loglevel=error"], cwd=ENGINES, check=True)
    sys.path.insert(0, str(SOURCE))
    from lightprobe.viewer.server import module_files  # the page's own list: its entry modules and their imports

    temp = dest.with_name(f".{dest.name}.tmp-{os.getpid()}")
    shutil.rmtree(temp, ignore_errors=True)
    for rel in [*module_files(root), "LICENSE"]:
        (temp / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(root / rel, temp / rel)
    (temp / "VERSION").write_text(version + "\n")
    shutil.rmtree(dest, ignore_errors=True)
    dest.parent.mkdir(parents=True, exist_ok=True)
    os.replace(temp, dest)
    return dest


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    print(vendor_three(Path(sys.argv[1])))
