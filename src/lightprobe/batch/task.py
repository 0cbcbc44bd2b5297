"""What a worker does with one input: the same API calls, with the same options, as the single-file commands
(``lightprobe sh``, ``lights``, ``irradiance``, ``radiance``), so a batch row equals the single-file result bit for
bit. The worker reads the file itself (no image bytes pass through the driver or the scheduler), writes its
artifacts atomically under ``OUT/maps/<sha256[:2]>/<sha256>/``, and returns a plain dict: a result row, an error
row, or a skip. It never raises: a corrupt, truncated or hostile file is one error row.
"""

from __future__ import annotations

import hashlib
import math
import os
import resource
import socket
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

JOBS = ("sh", "lights", "irradiance", "radiance", "thumbnail")
DEFAULT_JOBS = ("sh", "lights", "thumbnail")
WORKING_BYTES_PER_PIXEL = 64  # as the single-file commands' load(): directions and solid angles per pixel
IRRADIANCE_SIZE = 32  # lightprobe irradiance's default: a 64×32 latlong
THUMBNAIL_SIZE = 64  # a 128×64 latlong
RADIANCE_SIZE = 64


@dataclass(frozen=True)
class JobOptions:
    """The options every input is processed with (the same for all, recorded in the batch's manifest).

    Parameters
    ----------
    jobs : tuple of str
        The jobs to run after reading, in this order, among :data:`JOBS`: ``sh``, ``lights``, ``irradiance``,
        ``radiance``, ``thumbnail``. Default :data:`DEFAULT_JOBS` (sh, lights, thumbnail).
    order : int
        SH order of the ``sh`` and ``irradiance`` jobs. Default 2.
    brdf : str
        BRDF spec of the ``radiance`` job (:func:`lightprobe.glossy.brdf.parse_brdf`). Default ``ggx:alpha=0.2``.
    radiance_views : int
        Geodesic views of the ``radiance`` job: 12 (default), 42 or 162.
    radiance_size : int
        Texels on a side of each radiance map. Default :data:`RADIANCE_SIZE` (64).
    """

    jobs: tuple[str, ...] = DEFAULT_JOBS
    order: int = 2
    brdf: str = "ggx:alpha=0.2"
    radiance_views: int = 12
    radiance_size: int = RADIANCE_SIZE

    def as_dict(self) -> dict:
        """The options as a plain dict, as the manifest records them.

        Returns
        -------
        dict
            Every field by name, ``jobs`` as a list (JSON-ready).
        """
        d = asdict(self)
        d["jobs"] = list(self.jobs)
        return d


def file_digest(path: Path) -> tuple[str, int]:
    """sha256 (hex) and size of a file.

    Parameters
    ----------
    path : Path
        A regular file, read in 1 MiB blocks.

    Returns
    -------
    digest : str
        The SHA-256 of its bytes, 64 hex digits.
    size : int
        Its size in bytes.

    Raises
    ------
    OSError
        The file cannot be read, or is not a regular file.
    """
    from ..util.files import digest_file

    h = hashlib.sha256()
    size = digest_file(path, h)
    return h.hexdigest(), size


def artifact_folder(out: Path, digest: str) -> Path:
    """Where an input's artifacts go: ``out``/maps/<digest[:2]>/<digest>.

    Parameters
    ----------
    out : Path
        The batch folder.
    digest : str
        The SHA-256 (hex) of the input's bytes (:func:`file_digest`).

    Returns
    -------
    Path
        The folder; not created here.
    """
    return out / "maps" / digest[:2] / digest


def _limit_threads() -> None:
    """One compiled-kernel thread per worker: the pool, not numba, spreads the work over the cores
    (:func:`lightprobe.util.jit.use_threads` reads it as the kernels load)."""
    os.environ["LIGHTPROBE_THREADS"] = "1"


def process(path: str, options: JobOptions, out: str, skip: frozenset = frozenset()) -> dict:
    """One input → ``{"kind": "row" | "error" | "skipped", …}``; ``skip``: content hashes already in the table.

    See :mod:`lightprobe.batch.table` for the row's fields. The file is hashed before and after it is processed: one
    replaced or rewritten meanwhile is an error, never a row whose numbers are of other bytes than its ``sha256``.
    It never raises for a bad input: whatever the file
    provokes (a corrupt, truncated or hostile file, or running out of memory) is one error row. It sets
    ``LIGHTPROBE_THREADS`` to 1 in this process: one kernel thread per worker.

    Parameters
    ----------
    path : str
        The input file, read by this process.
    options : JobOptions
        The jobs and their options.
    out : str
        The batch folder; artifacts are written atomically under ``maps/<sha256[:2]>/<sha256>/``.
    skip : frozenset
        SHA-256 (hex) of contents already in the table: such an input is hashed and skipped. Default empty.

    Returns
    -------
    dict
        ``kind`` "row": the row's fields with ``seconds``, ``peak_rss`` (this process's peak resident bytes so far),
        ``worker`` (host:pid) and ``warnings``; "error": ``path``, ``sha256`` and ``size`` (None when unreadable),
        ``error_class``, ``message`` (one line) and ``worker``; "skipped": ``path``, ``sha256``, ``size`` and
        ``worker``.
    """
    _limit_threads()
    t0 = time.perf_counter()
    base = {"path": path, "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        digest, size = file_digest(Path(path))
    except (OSError, ValueError) as e:  # ValueError: a listed path with a NUL byte, which no file can have
        return {**base, "kind": "error", "error_class": "InputError",
                "message": f"cannot read {path!r}: {getattr(e, 'strerror', None) or e}", "sha256": None,
                "size": None}
    base.update(sha256=digest, size=size)
    if digest in skip:
        return {**base, "kind": "skipped"}
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            row = _row(Path(path), digest, options, Path(out))
        row["warnings"] = sorted({" ".join(str(w.message).split())[:300] for w in caught
                                  if w.category.__name__ == "LightprobeWarning"})
    except MemoryError:
        return {**base, "kind": "error", "error_class": "MemoryError", "message": "out of memory"}
    except Exception as e:  # noqa: BLE001 - whatever a hostile file provokes is that file's error, not the batch's
        from ..util.errors import LightprobeError

        text = " ".join(str(e).split())[:500] or type(e).__name__
        if not isinstance(e, LightprobeError):
            text = f"{type(e).__name__}: {text}"
        return {**base, "kind": "error", "error_class": type(e).__name__, "message": text}
    try:
        changed = file_digest(Path(path)) != (digest, size)
    except (OSError, ValueError):
        changed = True
    if changed:  # the numbers may be of other bytes than the hash: neither is recorded
        return {**base, "kind": "error", "error_class": "InputError",
                "message": f"{path} changed while it was processed (its sha256 before and after differ): run the "
                           "batch again with --resume once it is written"}
    row.update(base, kind="row", seconds=time.perf_counter() - t0,
               peak_rss=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
    return row


def _row(path: Path, digest: str, options: JobOptions, out: Path) -> dict:
    from .. import __version__
    from ..maps.files import read_envmap_within_budget
    from ..maps.images import image_header

    timings = {}
    t = time.perf_counter()
    env = read_envmap_within_budget(path, working_bytes_per_pixel=WORKING_BYTES_PER_PIXEL, kernels=True)
    header = image_header(path)  # the file's own width and height (a cross's or a strip's, not the grid's)
    timings["read"] = time.perf_counter() - t
    folder = artifact_folder(out, digest)
    row = {"layout": env.layout.name, "width": int(header.width), "height": int(header.height),
           "integral": [float(v) for v in env.integral()], "lightprobe_version": __version__,
           "sh": None, "sh_order": None, "lights": None, "light_count": None,
           "lights_json": None, "irradiance": None, "radiance": None, "thumbnail": None}
    for job in options.jobs:
        t = time.perf_counter()
        _as_a_fresh_command(job)
        JOB_FUNCTIONS[job](env, path, options, folder, out, row)
        timings[job] = time.perf_counter() - t
    row["timings"] = timings
    return row


# The SH projection takes numba or numpy by what the process has loaded (lightprobe.util.jit.worth_compiling), and the
# two agree to the last bits only. A fresh `lightprobe sh` or `irradiance` has not loaded numba when it projects
# (the choice is by the map's size alone); `lights` and `radiance` have, through their own kernels, before theirs.
FRESH_COMPILE_POLICY = {"sh": "by-work", "irradiance": "by-work"}


def _as_a_fresh_command(job: str) -> None:
    if job in FRESH_COMPILE_POLICY:
        os.environ["LIGHTPROBE_COMPILE"] = FRESH_COMPILE_POLICY[job]
    else:
        os.environ.pop("LIGHTPROBE_COMPILE", None)


def _sh(env, path, options, folder, out, row) -> None:
    from ..sh.basis import project

    sh = project(env, options.order, "world").windowed("none")  # lightprobe sh FILE --order N (defaults)
    row["sh"] = [float(v) for v in sh.coeffs.reshape(-1)]
    row["sh_order"] = options.order


def _lights(env, path, options, folder, out, row) -> None:
    from ..util.files import write_text
    from ..lights.hybrid import DEFAULT_AMBIENT_ORDER
    from ..lights.decompose import LightParams, decompose
    from ..lights.lightsfile import lights_json
    from ..sh.basis import project

    params = LightParams()  # lightprobe lights FILE -o X (defaults)
    params.check()
    dec = decompose(env, params)
    text = lights_json(dec, project(dec.ambient, DEFAULT_AMBIENT_ORDER), str(path))  # lights' --ambient-order
    folder.mkdir(parents=True, exist_ok=True)
    write_text(folder / "lights.json", text)
    row["lights_json"] = str((folder / "lights.json").relative_to(out))
    row["light_count"] = len(dec.lights)
    row["lights"] = [{"direction": [float(v) for v in light.direction],
                      "angular_radius_deg": math.degrees(light.radius), "solid_angle_sr": float(light.solid_angle),
                      "power": [float(v) for v in light.power], "radiance": [float(v) for v in light.radiance]}
                     for light in dec.lights]


def _irradiance(env, path, options, folder, out, row) -> None:
    from ..sh.irradiance import irradiance_map
    from ..maps.layouts import LATLONG

    folder.mkdir(parents=True, exist_ok=True)
    # lightprobe irradiance FILE -o X.exr --order N (latlong 64×32, SH, no window)
    irradiance_map(env, LATLONG, IRRADIANCE_SIZE, "sh", options.order, "none").to_envmap_image().save(
        folder / "irradiance.exr")
    row["irradiance"] = str((folder / "irradiance.exr").relative_to(out))


def _radiance(env, path, options, folder, out, row) -> None:
    from ..glossy.brdf import parse_brdf
    from ..glossy.radiance import geodesic_views, prepare
    from ..glossy.radiancefile import radiance_set, write_radiance_set

    brdf = parse_brdf(options.brdf)  # lightprobe radiance FILE --brdf B --views V --size S -o DIR
    rset = radiance_set(prepare(env), brdf, *geodesic_views(options.radiance_views), options.radiance_size)
    folder.mkdir(parents=True, exist_ok=True)
    write_radiance_set(folder / "radiance", rset, source=str(path))
    row["radiance"] = str((folder / "radiance").relative_to(out))


def _thumbnail(env, path, options, folder, out, row) -> None:
    from ..maps.images import write_image
    from ..maps.layouts import LATLONG
    from ..maps.tonemap import auto_exposure

    small = env.to(LATLONG, THUMBNAIL_SIZE)
    folder.mkdir(parents=True, exist_ok=True)
    write_image(folder / "thumbnail.png", small.data, exposure=auto_exposure(small.data, small.solid_angles()),
                curve="aces")
    row["thumbnail"] = str((folder / "thumbnail.png").relative_to(out))


JOB_FUNCTIONS = {"sh": _sh, "lights": _lights, "irradiance": _irradiance, "radiance": _radiance,
                 "thumbnail": _thumbnail}
