"""``manifest.json`` of a baked engine folder: the versioned schema ``lightprobe.bake``, its writer and its reader.

Version 1, one JSON object::

    format      "lightprobe.bake"
    version     1
    engine      the engine's name (lightprobe.util.names.BAKE_ENGINES)
    generator   "lightprobe <version>"
    source      {name, sha256, layout, grid, integral}: the probe, integral = ∫L dω per channel after the intensity
    parameters  the bake's options (BakeOptions.as_dict)
    frame       {name, description}: the frame every direction of the folder's files is stated in
    files       [{path, role, quantity, units, frame, encoding, layout, ..., bytes, sha256}], one per file but
                manifest.json itself: ``quantity`` radiance | irradiance | irradiance/pi | sh-radiance | … says what
                the numbers are; ``roughness`` (specular chains) gives each level's perceptual roughness
    lights      [{travel, toward, colour, intensity, angular_radius_deg}] when the bake found lights, else absent
    accuracy    how far each approximation in the files is from its brute-force integral (see bake.accuracy)
    timings     seconds by step

Every file's ``path`` is relative, inside the folder, and names a regular file there; the reader checks the schema
and never follows a path out of the folder.
"""

from __future__ import annotations

import json
import re
from pathlib import PurePosixPath

from ..util.errors import InputError

FORMAT = "lightprobe.bake"
VERSION = 1
MAX_BYTES = 4 << 20  # a manifest lists a few dozen files; anything larger is not one of ours
REQUIRED = ("format", "version", "engine", "generator", "source", "parameters", "frame", "files")
FILE_FIELDS = ("path", "role", "quantity", "encoding", "bytes", "sha256")
_SHA256 = re.compile(r"[0-9a-f]{64}")


def manifest_text(document: dict) -> str:
    """The manifest's JSON text: indented, finite numbers only, ending in a newline.

    Parameters
    ----------
    document : dict
        The version-1 object (see the module docstring).

    Returns
    -------
    str
        ``json.dumps`` of it with ``allow_nan=False``.
    """
    return json.dumps(document, indent=1, allow_nan=False) + "\n"


def _fail(what: str, message: str):
    raise InputError(f"{what}: {message}")


def read_bake_manifest(text: str | bytes, what: str = "bake manifest") -> dict:
    """A ``lightprobe.bake`` version-1 manifest, its schema checked.

    Parameters
    ----------
    text : str or bytes
        The manifest's JSON text, at most MAX_BYTES (4 MiB).
    what : str, default "bake manifest"
        What is read, for messages.

    Returns
    -------
    dict
        The document as written.

    Raises
    ------
    InputError
        Too large, not JSON, not a version-1 ``lightprobe.bake`` object, a required field missing or of the wrong
        type, or a file entry whose path is absolute, leaves the folder, or whose size or SHA-256 is malformed.
    """
    if len(text) > MAX_BYTES:
        _fail(what, f"larger than {MAX_BYTES >> 20} MiB")
    try:
        doc = json.loads(text)
    except (ValueError, UnicodeDecodeError, RecursionError) as e:
        _fail(what, f"not JSON ({type(e).__name__})")
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        _fail(what, f"not a {FORMAT} manifest")
    if doc.get("version") != VERSION:
        _fail(what, f"version {doc.get('version')!r} is not {VERSION}: bake again with this lightprobe")
    missing = [k for k in REQUIRED if k not in doc]
    if missing:
        _fail(what, f"missing {', '.join(missing)}")
    for key, kind in (("engine", str), ("generator", str), ("source", dict), ("parameters", dict), ("frame", dict),
                      ("files", list)):
        if not isinstance(doc[key], kind):
            _fail(what, f"{key} must be a {kind.__name__}")
    seen = set()
    for i, entry in enumerate(doc["files"]):
        if not isinstance(entry, dict) or any(k not in entry for k in FILE_FIELDS):
            _fail(what, f"files[{i}] must be an object with {', '.join(FILE_FIELDS)}")
        path = entry["path"]
        if not isinstance(path, str) or not path or "\\" in path or "\0" in path:
            _fail(what, f"files[{i}].path must be a relative POSIX path")
        parts = path.split("/")  # as written: "a/./b" or "a//b" is not a name a bake writes
        if PurePosixPath(path).is_absolute() or any(p in ("..", ".", "") for p in parts) or path in seen:
            _fail(what, f"files[{i}].path {path!r} leaves the folder or repeats")
        seen.add(path)
        size = entry["bytes"]
        if isinstance(size, bool) or not isinstance(size, int) or size < 0:
            _fail(what, f"files[{i}].bytes must be a non-negative whole number")
        if not isinstance(entry["sha256"], str) or not _SHA256.fullmatch(entry["sha256"]):
            _fail(what, f"files[{i}].sha256 must be 64 lowercase hex digits")
    return doc
