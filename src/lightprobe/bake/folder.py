"""One engine's folder as it is built: its files, what each holds, and the manifest and usage notes written last.

A bake builds every engine's folder inside a temporary folder beside ``-o`` and renames the whole into place only
once every file is written (:mod:`lightprobe.bake.run`), so the folders here are never seen half-written.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..maps.frames import Frame
from ..maps.images import write_image
from .manifest import FORMAT, VERSION, manifest_text

MANIFEST = "manifest.json"
USAGE = "USAGE.md"


@dataclass
class EngineFolder:
    """The folder of one engine's files, and the manifest entries that describe them.

    Attributes
    ----------
    path : Path
        The folder (inside the bake's temporary folder while it is built).
    engine : str
        The engine's name.
    frame : Frame
        The frame the folder's directions are stated in.
    files : list of dict
        One manifest entry per file written so far.
    """

    path: Path
    engine: str
    frame: Frame
    files: list[dict] = field(default_factory=list)

    def add_bytes(self, name: str, data: bytes, role: str, quantity: str, encoding: str, **meta) -> Path:
        """Write ``data`` as ``name`` and record it.

        Parameters
        ----------
        name : str
            The file's path inside the folder (POSIX, relative; subfolders are made).
        data : bytes
            The file's contents.
        role : str
            What the engine uses it for: ``specular``, ``diffuse``, ``skybox``, ``lights``, ``dfg``, ``scene`` …
        quantity : str
            What the numbers are: ``radiance``, ``irradiance``, ``irradiance/pi``, ``sh-radiance`` …
        encoding : str
            How they are stored (``RGBA16F``, ``RGBD PNG``, ``JSON`` …).
        **meta
            Further manifest fields (``layout``, ``size``, ``mips``, ``roughness``, ``units``, ``frame`` …).

        Returns
        -------
        Path
            The file written.
        """
        target = self.path / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
        self._record(name, data, role, quantity, encoding, meta)
        return target

    def add_text(self, name: str, text: str, role: str, quantity: str, encoding: str = "text", **meta) -> Path:
        """Write ``text`` (UTF-8) as ``name`` and record it; see :meth:`add_bytes`.

        Parameters
        ----------
        name : str
            The file's path inside the folder.
        text : str
            Its contents.
        role : str
            What the engine uses it for.
        quantity : str
            What the numbers are.
        encoding : str, default "text"
            How they are stored (``JSON``, ``C#`` …).
        **meta
            Further manifest fields.

        Returns
        -------
        Path
            The file written.
        """
        return self.add_bytes(name, text.encode("utf-8"), role, quantity, encoding, **meta)

    def add_image(self, name: str, rgb: np.ndarray, role: str, quantity: str, **meta) -> Path:
        """Write linear float RGB as an image file (the extension picks the format: .exr float32, .hdr RGBE).

        Parameters
        ----------
        name : str
            The file's path inside the folder, with its extension.
        rgb : numpy.ndarray
            (H, W, 3) linear values.
        role : str
            What the engine uses it for.
        quantity : str
            What the numbers are.
        **meta
            Further manifest fields.

        Returns
        -------
        Path
            The file written.
        """
        target = self.path / name
        target.parent.mkdir(parents=True, exist_ok=True)
        write_image(target, np.ascontiguousarray(rgb, np.float32))
        encoding = {".exr": "OpenEXR float32", ".hdr": "Radiance RGBE"}.get(target.suffix.lower(), target.suffix)
        self._record(name, target.read_bytes(), role, quantity, encoding, meta)
        return target

    def _record(self, name: str, data: bytes, role: str, quantity: str, encoding: str, meta: dict) -> None:
        entry = {"path": name, "role": role, "quantity": quantity, "encoding": encoding,
                 "frame": meta.pop("frame", self.frame.name)}
        entry.update(meta)
        entry.update({"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()})
        self.files.append(entry)

    def finish(self, usage: str, header: dict, extra: dict) -> None:
        """Write ``USAGE.md`` and then ``manifest.json`` naming every file.

        Parameters
        ----------
        usage : str
            The Markdown notes: the engine code that loads the folder.
        header : dict
            ``generator``, ``source`` and ``parameters`` (the same for every engine of a bake).
        extra : dict
            The engine's ``lights``, ``accuracy``, ``timings`` and any further fields.
        """
        self.add_text(USAGE, usage, "usage", "none", "Markdown")
        document = {"format": FORMAT, "version": VERSION, "engine": self.engine, **header,
                    "frame": {"name": self.frame.name, "description": self.frame.description},
                    "files": self.files, **extra}
        (self.path / MANIFEST).write_text(manifest_text(document), encoding="utf-8")
