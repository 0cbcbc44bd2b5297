"""The batch's table: a versioned Parquet schema, part files committed by rename, a manifest, and consolidation.

Layout of ``OUT``::

    batch.json                 manifest: format lightprobe.batch, version, schema version, lightprobe version, options
    parts/rows-NNNNNN-<id>.parquet, parts/errors-NNNNNN-<id>.parquet
                               the committed chunks: each written to a temporary name and renamed (the commit)
    results.parquet            every input's row, once (made from the parts at the end of each run)
    errors.parquet             every failed input, once
    maps/<sha[:2]>/<sha>/      artifacts (lights.json, irradiance.exr, thumbnail.png, radiance/)

``results.parquet`` columns (schema version 1): ``path`` (absolute), ``sha256``, ``size`` (bytes), ``layout``,
``width``, ``height``, ``integral`` (∫L dω per channel, radiance × sr, fixed-size list of 3), ``sh`` (radiance SH
L_lm, world frame, real basis without Condon–Shortley phase, flat l(l+1)+m × RGB: a fixed-size list of
3(order + 1)² float64; the order is in the schema metadata ``lightprobe.sh_order`` and in ``sh_order``),
``light_count``, ``lights`` (list of structs: direction (world, unit), angular_radius_deg, solid_angle_sr, power,
radiance), ``lights_json``/``irradiance``/``radiance``/``thumbnail`` (artifact paths relative to ``OUT``),
``timings`` (seconds per job), ``seconds``, ``peak_rss`` (the worker's peak resident bytes so far), ``worker``,
``warnings``, ``lightprobe_version``. ``errors.parquet``: ``path``, ``sha256`` and ``size`` (null when unreadable),
``error_class``, ``message`` (one line), ``worker``, ``lightprobe_version``.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import stat
from pathlib import Path

from ..util.errors import UsageError

FORMAT, VERSION, SCHEMA_VERSION = "lightprobe.batch", 1, 1
MAX_MANIFEST_BYTES = 1 << 20  # batch.json holds the versions and options: a few hundred bytes
PART_NAME = re.compile(r"(rows|errors)-(\d{6,})-([0-9a-f]{8})\.parquet")  # what Parts.commit names a part
JOB_NAMES = ("read", "sh", "lights", "irradiance", "radiance", "thumbnail")


def _pa():
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise UsageError("'lightprobe batch' needs the optional 'pyarrow' package: "
                         "pip install 'lightprobe[batch]'") from None
    return pa, pq


def row_schema(order: int | None):
    """The Arrow schema of ``results.parquet`` and of the rows parts (schema version 1).

    Its columns are those the module docstring lists.

    Parameters
    ----------
    order : int or None
        SH order of the ``sh`` column, a fixed-size list of 3(order + 1)² float64 (l(l+1)+m × RGB); None (no ``sh``
        job): a list of any size, and the metadata's ``lightprobe.sh_order`` empty.

    Returns
    -------
    pyarrow.Schema
        The schema, its metadata naming the format, the schema version, the SH order, frame (world), quantity
        (radiance) and basis.

    Raises
    ------
    UsageError
        pyarrow is not installed.
    """
    pa, _ = _pa()
    vec3 = pa.list_(pa.float64(), 3)
    light = pa.struct([("direction", vec3), ("angular_radius_deg", pa.float64()), ("solid_angle_sr", pa.float64()),
                       ("power", vec3), ("radiance", vec3)])
    sh_width = 3 * (order + 1) ** 2 if order is not None else 0
    fields = [
        ("path", pa.string()), ("sha256", pa.string()), ("size", pa.int64()), ("layout", pa.string()),
        ("width", pa.int32()), ("height", pa.int32()), ("integral", vec3),
        ("sh", pa.list_(pa.float64(), sh_width) if sh_width else pa.list_(pa.float64())), ("sh_order", pa.int32()),
        ("light_count", pa.int32()), ("lights", pa.list_(light)),
        ("lights_json", pa.string()), ("irradiance", pa.string()), ("radiance", pa.string()),
        ("thumbnail", pa.string()), ("timings", pa.struct([(j, pa.float64()) for j in JOB_NAMES])),
        ("seconds", pa.float64()), ("peak_rss", pa.int64()), ("worker", pa.string()),
        ("warnings", pa.list_(pa.string())), ("lightprobe_version", pa.string()),
    ]
    meta = {"lightprobe.format": FORMAT, "lightprobe.schema_version": str(SCHEMA_VERSION),
            "lightprobe.sh_order": "" if order is None else str(order), "lightprobe.sh_frame": "world",
            "lightprobe.sh_quantity": "radiance", "lightprobe.sh_basis": "real, no Condon-Shortley phase, l(l+1)+m, RGB"}
    return pa.schema(fields, metadata=meta)


def error_schema():
    """The Arrow schema of ``errors.parquet`` and of the errors parts.

    Returns
    -------
    pyarrow.Schema
        ``path``, ``sha256``, ``size``, ``error_class``, ``message``, ``worker`` and ``lightprobe_version``, with the
        format and schema version in its metadata.

    Raises
    ------
    UsageError
        pyarrow is not installed.
    """
    pa, _ = _pa()
    return pa.schema([("path", pa.string()), ("sha256", pa.string()), ("size", pa.int64()),
                      ("error_class", pa.string()), ("message", pa.string()), ("worker", pa.string()),
                      ("lightprobe_version", pa.string())],
                     metadata={"lightprobe.format": FORMAT, "lightprobe.schema_version": str(SCHEMA_VERSION)})


# ---- the manifest -----------------------------------------------------------------------------------------------
def manifest(options: dict) -> dict:
    """The manifest ``batch.json`` of a batch made with ``options``.

    Parameters
    ----------
    options : dict
        The job options, as :meth:`lightprobe.batch.task.JobOptions.as_dict` gives them.

    Returns
    -------
    dict
        Format, batch format version, schema version, this lightprobe's version and the options.
    """
    from .. import __version__

    return {"format": FORMAT, "version": VERSION, "schema_version": SCHEMA_VERSION, "lightprobe": __version__,
            "options": options}


def read_manifest(out: Path) -> dict | None:
    """The manifest of the batch in ``out``, or None when there is none.

    Parameters
    ----------
    out : Path
        The batch folder; its ``batch.json`` is read.

    Returns
    -------
    dict or None
        The manifest; None when ``batch.json`` does not exist.

    Raises
    ------
    UsageError
        ``batch.json`` is unreadable, not JSON, or not a lightprobe batch manifest.
    """
    from ..util.errors import LightprobeError
    from ..util.files import read_bounded

    if not os.path.lexists(out / "batch.json"):
        return None
    try:
        doc = json.loads(read_bounded(out / "batch.json", MAX_MANIFEST_BYTES, "batch manifest"))
    except (LightprobeError, ValueError) as e:
        raise UsageError(f"{out}/batch.json is unreadable ({e}): not a batch folder this version can resume") \
            from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise UsageError(f"{out}/batch.json is not a lightprobe batch manifest")
    return doc


def write_manifest(out: Path, doc: dict) -> None:
    """Write ``doc`` as ``out``/batch.json, atomically (:func:`lightprobe.util.files.write_text`).

    Parameters
    ----------
    out : Path
        The batch folder, which must exist.
    doc : dict
        The manifest (:func:`manifest`), written as indented JSON.
    """
    from ..util.files import write_text

    write_text(out / "batch.json", json.dumps(doc, indent=1) + "\n")


# ---- parts --------------------------------------------------------------------------------------------------------
class Parts:
    """The committed chunks of one batch folder, and the writer of new ones.

    Made on a folder, it removes the temporary files of parts that were being written when a driver died (never
    committed), and numbers new parts after the highest committed one.

    Parameters
    ----------
    out : Path
        The batch folder; its ``parts/`` folder is made if needed.
    order : int or None
        SH order of the rows' ``sh`` column (:func:`row_schema`); None without the ``sh`` job.

    Raises
    ------
    UsageError
        ``parts/`` holds a file that is not a part this batch wrote (nor a hidden one), or a part's name on anything
        but a regular file (a FIFO, device, socket, link or folder: it is never opened).
    """

    def __init__(self, out: Path, order: int | None):
        self.folder = out / "parts"
        self.folder.mkdir(parents=True, exist_ok=True)
        self.order = order
        for stale in self.folder.glob(".*.tmp"):  # a part being written when the driver died: never committed
            stale.unlink(missing_ok=True)
        numbers = []
        for path in self.folder.iterdir():
            match = PART_NAME.fullmatch(path.name)
            if match is None and not path.name.startswith("."):
                raise UsageError(f"{path} is not a part this batch wrote (rows-NNNNNN-xxxxxxxx.parquet or "
                                 "errors-…): move it out of the folder to resume")
            if match is not None:
                if not stat.S_ISREG(path.lstat().st_mode):  # a FIFO would block the read for ever
                    raise UsageError(f"{path} is not a regular file (a FIFO, device, socket, link or folder), so not "
                                     "a part this batch wrote: move it out of the folder to resume")
                numbers.append(int(match.group(2)))
        self.sequence = 1 + max(numbers, default=0)

    def commit(self, kind: str, rows: list[dict]) -> Path | None:
        """Write ``rows`` as one part (``kind`` rows or errors): to a temporary name, fsync, rename.

        Parameters
        ----------
        kind : str
            ``rows`` (with :func:`row_schema`) or ``errors`` (with :func:`error_schema`).
        rows : list of dict
            One dict per input; keys outside the schema are ignored, missing ones are null.

        Returns
        -------
        Path or None
            The committed part, ``parts/KIND-NNNNNN-xxxxxxxx.parquet``; None when ``rows`` is empty (nothing written).
        """
        if not rows:
            return None
        pa, pq = _pa()
        schema = row_schema(self.order) if kind == "rows" else error_schema()
        table = pa.Table.from_pylist([{f: r.get(f) for f in schema.names} for r in rows], schema=schema)
        name = f"{kind}-{self.sequence:06d}-{secrets.token_hex(4)}.parquet"
        self.sequence += 1
        temp = self.folder / f".{name}.tmp"
        pq.write_table(table, temp)
        with open(temp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(temp, self.folder / name)
        _fsync_folder(self.folder)
        return self.folder / name

    def read(self, kind: str):
        """Every committed part of ``kind`` as one table (empty with the schema when none).

        A part that does not read back with the schema — parts are renamed into place whole, so only something outside
        the batch damages one — stops the run with one line naming it.

        Parameters
        ----------
        kind : str
            ``rows`` or ``errors``.

        Returns
        -------
        pyarrow.Table
            The parts' rows concatenated in the order of their names (their commit order).

        Raises
        ------
        UsageError
            A part is damaged; the message says to move it out and resume.
        """
        pa, _ = _pa()
        schema = row_schema(self.order) if kind == "rows" else error_schema()
        tables = [_read_checked(path, lambda found, s=schema: s, "is damaged", "move it out of the folder and "
                                "resume with --resume, which redoes its inputs")
                  for path in sorted(self.folder.glob(f"{kind}-*.parquet"))]
        return pa.concat_tables(tables) if tables else schema.empty_table()


def read_finished(path: Path, kind: str):
    """A consolidated ``results.parquet`` or ``errors.parquet``, checked against its schema.

    ``results.parquet`` with ``kind`` "rows", ``errors.parquet`` with "errors"; the SH order of the rows' schema comes
    from the file's own metadata: a :class:`UsageError` naming the file when it is not one this batch format writes.

    Parameters
    ----------
    path : Path
        The Parquet file.
    kind : str
        ``rows`` for ``results.parquet``; anything else reads with the errors' schema.

    Returns
    -------
    pyarrow.Table
        The table, read with the schema.

    Raises
    ------
    UsageError
        The file is not a lightprobe batch table (a column missing or of another type, unreadable, …).
    """
    return _read_checked(path, lambda found: row_schema(_order_of(found)) if kind == "rows" else error_schema(),
                         "is not a lightprobe batch table", "rerun the batch with --resume, which writes it again "
                         "from its parts")


def _read_checked(path: Path, schema_for, what: str, remedy: str):
    """The Parquet file ``path`` read with the schema ``schema_for(its own schema)`` gives, once every column of
    that schema is there with its type (read_table alone would fill missing columns with nulls); anything else is
    a :class:`UsageError`: "``path`` ``what`` (reason): ``remedy``"."""
    pa, pq = _pa()
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # never waits: what is not a regular file is refused below
        with os.fdopen(fd, "rb") as f:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise ValueError("not a regular file (a FIFO, device or socket)")
            found = pq.read_schema(f)
            schema = schema_for(found)
            _check_columns(found, schema)
            f.seek(0)
            # One thread: a batch table is small, and no Arrow reader thread is left running when a program that
            # called this exits (Arrow's pool can abort the process if one is).
            return pq.read_table(f, schema=schema, use_threads=False)
    except (pa.ArrowException, OSError, ValueError) as e:
        reason = " ".join(str(e).split())[:200]
        raise UsageError(f"{path} {what} ({reason}): {remedy}") from None


def _order_of(schema) -> int | None:
    text = (schema.metadata or {}).get(b"lightprobe.sh_order", b"").decode("utf-8", "replace")
    if not text:
        return None
    if not text.isdigit() or int(text) > 64:
        raise ValueError(f"SH order {text[:20]!r} in its metadata")
    return int(text)


def _check_columns(found, wanted) -> None:
    """ValueError unless schema ``found`` has every column of ``wanted``, each of its type."""
    for field in wanted:
        index = found.get_field_index(field.name)
        if index < 0 or not found.field(index).type.equals(field.type):
            got = "missing" if index < 0 else str(found.field(index).type)
            raise ValueError(f"column {field.name}: {got}, not {field.type}")


def _fsync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError:
        pass


def done_keys(parts: Parts) -> tuple[set[str], set[str]]:
    """Paths already recorded (rows or errors) and content hashes already in the rows.

    Parameters
    ----------
    parts : Parts
        The batch folder's committed parts.

    Returns
    -------
    paths : set of str
        Input paths with a committed row or error.
    hashes : set of str
        SHA-256 (hex) of the inputs with a committed row.

    Raises
    ------
    UsageError
        A part is damaged.
    """
    rows, errors = parts.read("rows"), parts.read("errors")
    paths = set(rows.column("path").to_pylist()) | set(errors.column("path").to_pylist())
    return paths, set(rows.column("sha256").to_pylist())


def consolidate(out: Path, parts: Parts) -> tuple[int, int]:
    """Write ``results.parquet`` and ``errors.parquet`` from the parts, each input once.

    Rows and errors are kept by path (the first committed kept: inputs with the same bytes have a row each), and no
    error for a path that has a row;
    both sorted by path. Each file is written to a temporary name and renamed (atomic each).

    Parameters
    ----------
    out : Path
        The batch folder, where both files are written.
    parts : Parts
        Its committed parts.

    Returns
    -------
    rows : int
        Rows written to ``results.parquet``.
    errors : int
        Rows written to ``errors.parquet``.
    """
    import pyarrow.compute as pc

    _, pq = _pa()
    rows = _first_of_each(parts.read("rows"), "path")
    errors = _first_of_each(parts.read("errors"), "path")
    if errors.num_rows and rows.num_rows:
        errors = errors.filter(pc.invert(pc.is_in(errors.column("path"), value_set=rows.column("path"))))
    for name, table in (("results.parquet", rows), ("errors.parquet", errors)):
        table = table.sort_by("path") if table.num_rows else table
        temp = out / f".{name}.tmp-{os.getpid()}"
        pq.write_table(table, temp)
        os.replace(temp, out / name)
    return rows.num_rows, errors.num_rows


def _first_of_each(table, key: str):
    seen, keep = set(), []
    for i, k in enumerate(table.column(key).to_pylist()):
        if k not in seen:
            seen.add(k)
            keep.append(i)
    return table.take(keep) if len(keep) != table.num_rows else table
