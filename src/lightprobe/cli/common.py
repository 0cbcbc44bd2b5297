"""What every command shares: the parser, typed and bounded options, loading a probe within the memory budget,
and output that is always valid (JSON without NaN, files written safely)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from ..util.errors import LightprobeError, UsageError



class Parser(argparse.ArgumentParser):
    """argparse with one-line errors (and status 2) instead of the usage block."""

    def error(self, message: str):
        raise UsageError(f"{message} (see '{self.prog} --help')")


# ---- option types: each states its range in the help and refuses values outside it before any work -------------
class Number:
    """An integer or float option within [lo, hi]; NaN and infinities are refused."""

    def __init__(self, kind: type, lo: float, hi: float):
        self.kind, self.lo, self.hi = kind, lo, hi
        self.__name__ = "whole number" if kind is int else "number"

    @property
    def range_text(self) -> str:
        return f"{self.lo:g}..{self.hi:g}"

    def __call__(self, text: str):
        try:
            value = self.kind(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"must be a {self.__name__} within {self.range_text}, got "
                                             f"{text[:40]!r}") from None
        if not (math.isfinite(value) and self.lo <= value <= self.hi):
            raise argparse.ArgumentTypeError(f"must be within {self.range_text}, got {text[:40]!r}")
        return value

    def bad_examples(self) -> list[str]:
        return [str(self.lo - 1), str(self.hi + 1), "nan", "inf", "abc"]


class NumberList:
    """Comma-separated numbers, each within [lo, hi] (``--order 2,4,6``)."""

    def __init__(self, kind: type, lo: float, hi: float, most: int = 16):
        self.item, self.most = Number(kind, lo, hi), most
        self.__name__ = "list"

    @property
    def range_text(self) -> str:
        return f"each {self.item.range_text}, at most {self.most}"

    def __call__(self, text: str) -> list:
        parts = [p for p in text.split(",")]
        if not 1 <= len(parts) <= self.most or not all(p.strip() for p in parts):
            raise argparse.ArgumentTypeError(f"wants 1 to {self.most} comma-separated numbers, got {text[:40]!r}")
        return [self.item(p.strip()) for p in parts]

    def bad_examples(self) -> list[str]:
        return [*self.item.bad_examples(), "", "1,,2", ",".join(["1"] * (self.most + 1))]


class Triple(NumberList):
    """Exactly three comma-separated numbers (``--rotate yaw,pitch,roll``)."""

    def __init__(self, lo: float, hi: float):
        super().__init__(float, lo, hi, 3)

    @property
    def range_text(self) -> str:
        return f"three numbers, each {self.item.range_text}"

    def __call__(self, text: str) -> list:
        values = super().__call__(text)
        if len(values) != 3:
            raise argparse.ArgumentTypeError(f"wants three numbers such as 90,0,0, got {text[:40]!r}")
        return values

    def bad_examples(self) -> list[str]:
        return ["", "1,2", "1,2,nan", f"0,0,{self.item.hi * 2:g}", "a,b,c"]


class ImageSize:
    """``WxH`` (both within 1..hi) or, with ``single``, also a lone ``N``: returned as (w, h) or (N, None)."""

    def __init__(self, hi: int = 16384, single: bool = False):
        self.hi, self.single = hi, single
        self.__name__ = "size"

    @property
    def range_text(self) -> str:
        return (f"N or WxH, each 1..{self.hi}" if self.single else f"WxH, each 1..{self.hi}")

    def __call__(self, text: str):
        parts = text.lower().split("x")
        try:
            values = [int(p) for p in parts]
        except ValueError:
            values = []
        if not (len(values) == 2 or (self.single and len(values) == 1)) or not all(1 <= v <= self.hi
                                                                                  for v in values):
            raise argparse.ArgumentTypeError(f"wants {self.range_text}, got {text[:40]!r}")
        return (values[0], values[1] if len(values) == 2 else None)

    def bad_examples(self) -> list[str]:
        return ["0", "abc", f"{self.hi + 1}x16", "16x0", "-4x4", "2147483648x2"]


def add_option(p: argparse.ArgumentParser, *flags: str, type, help: str, **kwargs) -> None:
    """An option whose help ends with its range (and default), so the range is documented where it is checked."""
    default = kwargs.get("default")
    shown = f" ({type.range_text}" + (f"; default {default}" if default is not None else "") + ")"
    p.add_argument(*flags, type=type, help=help + shown, **kwargs)


# ---- probes -------------------------------------------------------------------------------------------------------
def layout_names() -> list[str]:
    from ..util.names import LAYOUTS

    return list(LAYOUTS)


def add_probe(p: argparse.ArgumentParser, name: str = "file", help_text: str | None = None,
              layout_flag: str = "--layout") -> None:
    p.add_argument(name, nargs="?", type=Path,
                   help=help_text or "HDR environment map (.hdr, .exr, .pfm, .png, …); omitted: the shipped probe")
    flags = (layout_flag, "-l") if layout_flag == "--layout" else (layout_flag,)
    p.add_argument(*flags, dest="layout", choices=layout_names(),
                   help="layout of the input; default: from its aspect ratio (2:1 latlong, 1:1 angular, 3:4 cross, "
                        "4:3 hcross, 6:1 cube strip)")


def probe_path(path: Path | None) -> Path:
    from ..data import default_probe_path

    return path or default_probe_path()


def load(path: Path | None, layout: str | None, fix: bool = True, working_bytes_per_pixel: int = 0,
         extra_bytes: int = 0, what: str = "", kernels: bool = False):
    """Read a probe (the shipped one when ``path`` is None) after checking that reading it plus
    ``working_bytes_per_pixel`` per pixel plus ``extra_bytes`` fits the memory budget (with numba's own memory
    when the command runs compiled ``kernels``)."""
    from ..maps.files import read_envmap_within_budget

    return read_envmap_within_budget(probe_path(path), layout, fix=fix, extra_bytes=extra_bytes, what=what,
                                     working_bytes_per_pixel=working_bytes_per_pixel, kernels=kernels)


# ---- output -------------------------------------------------------------------------------------------------------
def finite_json(value):
    """``value`` with every non-finite float replaced by None (JSON has no NaN or infinity)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_json(v) for v in value]
    return value


def print_json(value) -> None:
    sys.stdout.write(json.dumps(finite_json(value), allow_nan=False) + "\n")


def write_text(path: Path, text: str, inputs=()) -> None:
    from ..util.files import write_text as write

    write(path, text, inputs)


def refuse(message: str):
    raise LightprobeError(message)
