"""The wheel carries the viewer's three.js modules, copied at build time from the npm version pinned in
engines/package-lock.json (engines/vendor_three.py); everything else is in pyproject.toml."""

import importlib.util
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent


class BuildWithThree(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return  # a development install serves src/, where setup.sh puts the same files
        spec = importlib.util.spec_from_file_location("vendor_three", HERE / "engines" / "vendor_three.py")
        vendor = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(vendor)
        vendor.vendor_three(Path(self.build_lib) / "lightprobe" / "viewer" / "vendor" / "three")


setup(cmdclass={"build_py": BuildWithThree})
