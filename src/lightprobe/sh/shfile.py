"""lightprobe's SH JSON file: one versioned schema for ``sh --json``, ``export --to json`` and ``design --json``.

Schema ``{"format": "lightprobe.sh", "version": 2, ...}``:

* ``quantity``: ``radiance`` (L_lm) or ``irradiance`` (E_lm = Â_l L_lm, not divided by π);
* ``frame`` (a name of :data:`lightprobe.maps.frames.FRAMES`) and ``frame_description``: the frame whose +z the basis is
  built about;
* ``basis``: real SH without the Condon–Shortley phase, flat index l(l+1)+m (fixed text);
* ``window``: the de-ringing window applied (``none``, ``lanczos(3)``, …); ``l_max``; ``names`` (L00, L1-1, …);
* ``coefficients``: (l_max+1)² rows of [R, G, B];
* ``source``: the map the coefficients came from, or null.

:func:`read_sh_json` refuses anything else with one line (it is fuzzed in the tests).
"""

from __future__ import annotations

import json

import numpy as np

from ..util.errors import InputError
from ..maps.frames import FRAMES, WORLD, Frame
from .basis import QUANTITIES, SHCoeffs, n_coeffs, name

FORMAT, VERSION = "lightprobe.sh", 2
BASIS = "real SH, no Condon-Shortley phase, flat index l(l+1)+m (Ramamoorthi & Hanrahan 2001)"
MAX_ORDER = 64
MAX_BYTES = 4 << 20


def sh_document(sh: SHCoeffs, frame: Frame = WORLD, source: str | None = None) -> dict:
    """The schema's object for ``sh`` stated in ``frame``.

    Parameters
    ----------
    sh : SHCoeffs
        Coefficients of either quantity, any order, any frame.
    frame : Frame, default WORLD
        The frame to state them in (a frame name is accepted too); the file names it.
    source : str, optional
        The map the coefficients came from; null in the file when None.

    Returns
    -------
    dict
        The ``lightprobe.sh`` version 2 object (see the module docstring), ready for ``json.dumps``.
    """
    out = sh.to_frame(frame)
    return {"format": FORMAT, "version": VERSION, "quantity": out.quantity, "frame": out.frame.name,
            "frame_description": out.frame.description, "basis": BASIS, "window": out.window, "l_max": out.l_max,
            "names": [name(i) for i in range(n_coeffs(out.l_max))], "coefficients": out.as_list(),
            "source": source}


def sh_json(sh: SHCoeffs, frame: Frame = WORLD, source: str | None = None) -> str:
    """The schema's JSON text for ``sh`` stated in ``frame`` (:func:`sh_document`, indented, ending in a newline).

    Parameters
    ----------
    sh : SHCoeffs
        What to write, as for :func:`sh_document`.
    frame : Frame, default WORLD
        The frame the file states them in.
    source : str, optional
        The map projected, as the user named it, or None.

    Returns
    -------
    str
        ``lightprobe.sh`` text that :func:`read_sh_json` reads back; NaN and infinity are refused by ``json.dumps``
        (SHCoeffs never hold them).
    """
    return json.dumps(sh_document(sh, frame, source), indent=1, allow_nan=False) + "\n"


def versioned_document(text: str | bytes, what: str, fmt: str, version: int, max_bytes: int):
    """The JSON object of a ``{"format": fmt, "version": version, …}`` document and a ``fail(reason)`` to refuse it.

    ``fail(reason)`` raises the one-line :class:`~lightprobe.util.errors.InputError` "cannot read <what>: <reason>"
    (shared by lightprobe's readers).

    Parameters
    ----------
    text : str or bytes
        The document's text (bytes are decoded as JSON text by :func:`json.loads`).
    what : str
        What is read, for messages (e.g. ``"SH file"`` or a file name).
    fmt : str
        The required ``format`` field (``lightprobe.sh``, ``lightprobe.lights``, …).
    version : int
        The required ``version`` field.
    max_bytes : int
        The longest text accepted, in characters for a str and bytes for bytes.

    Returns
    -------
    doc : dict
        The parsed object, with ``format`` and ``version`` checked and nothing else.
    fail : callable taking a str
        Raises the one-line :class:`~lightprobe.util.errors.InputError` for a reason; it never returns.

    Raises
    ------
    InputError
        The text is over ``max_bytes``, is not JSON, is not an object of format ``fmt``, or has another version.
    """
    def fail(reason: str):
        raise InputError(f"cannot read {what}: {reason}")

    if len(text) > max_bytes:
        fail(f"over {max_bytes} bytes")
    try:
        doc = json.loads(text)
    except (ValueError, UnicodeDecodeError, RecursionError) as e:
        raise InputError(f"cannot read {what}: not JSON ({str(e).splitlines()[0][:120] if str(e) else 'invalid'})"
                         ) from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        fail(f"not a {fmt} document")
    if doc.get("version") != version:
        fail(f"version {json.dumps(doc.get('version'))[:20]} is not {version}")  # as JSON: one line, escaped
    return doc, fail


def read_sh_json(text: str | bytes, what: str = "SH file") -> SHCoeffs:
    """Coefficients from the schema's JSON text; every field is checked.

    Parameters
    ----------
    text : str or bytes
        A ``lightprobe.sh`` version 2 document, at most :data:`MAX_BYTES` (4 MiB).
    what : str, default "SH file"
        What is read, for messages (e.g. the file's name).

    Returns
    -------
    SHCoeffs
        The coefficients with the file's quantity, frame (they are not converted to the world frame) and window
        (``none`` when the field is missing).

    Raises
    ------
    InputError
        The text is not such a document, or a field is missing or wrong: quantity, frame (a name of
        :data:`lightprobe.maps.frames.FRAMES`), window (a text of at most 64 characters), l_max (0 to
        :data:`MAX_ORDER`), or coefficients ((l_max+1)² rows of three finite numbers).
    """
    doc, fail = versioned_document(text, what, FORMAT, VERSION, MAX_BYTES)
    quantity, frame, window, l_max = doc.get("quantity"), doc.get("frame"), doc.get("window", "none"), doc.get("l_max")
    if quantity not in QUANTITIES:
        fail("quantity must be radiance or irradiance")
    if not isinstance(frame, str) or frame not in FRAMES:
        fail(f"frame must be one of {', '.join(FRAMES)}")
    if not isinstance(window, str) or len(window) > 64:
        fail("window must be a short text")
    if isinstance(l_max, bool) or not isinstance(l_max, int) or not 0 <= l_max <= MAX_ORDER:
        fail(f"l_max must be a whole number within 0..{MAX_ORDER}")
    rows = doc.get("coefficients")
    if not isinstance(rows, list) or len(rows) != n_coeffs(l_max):
        fail(f"coefficients must be {n_coeffs(l_max)} rows for l_max {l_max}")
    if not all(isinstance(r, list) and len(r) == 3 and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                           for v in r) for r in rows):
        fail("each coefficient must be three numbers [R, G, B]")
    coeffs = np.array(rows, dtype=np.float64)
    if not np.isfinite(coeffs).all():
        fail("coefficients must be finite")
    return SHCoeffs(coeffs, FRAMES[frame], quantity, window)
