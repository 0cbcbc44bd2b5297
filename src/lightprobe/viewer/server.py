"""The viewer's HTTP server and its static export: the page, its modules and one bake folder, nothing else.

Safety, because a local server is reachable by every page the user's browser opens: it binds 127.0.0.1 only,
answers GET and HEAD (any other method 405), lists no folder, and serves only

* ``/`` — the page (``index.html``, made from the template in ``static/`` with its Content-Security-Policy),
* ``/static/NAME`` — the page's own files (the files in ``static/``, fixed when the server starts),
* ``/modules/three/…`` — the three.js modules the page imports (the package's own copy, made at build time from
  the pinned npm package: a fixed list of files),
* ``/bake/…`` — regular files inside the bake folder, reached without ``..``, ``.``-prefixed or empty segments
  (after percent-decoding), backslashes or NUL, and whose real path (symlinks followed) stays inside the folder.

Everything else is 404. Every answer carries the CSP, ``nosniff`` and a MIME type from :data:`MIME`.
The static export writes the same tree (``index.html``, ``static/``, ``modules/``, ``bake/``) into a folder, so the
page is the same file whether served here or from any static host.
"""

from __future__ import annotations

import base64
import hashlib
import http.server
import os
import re
import shutil
import threading
from collections.abc import Callable
from pathlib import Path
from urllib.parse import unquote

from ..util.errors import LightprobeError, UsageError

STATIC = Path(__file__).resolve().parent / "static"
ENTRY_MODULES = ("build/three.module.js", "examples/jsm/controls/OrbitControls.js",
                 "examples/jsm/loaders/GLTFLoader.js")
MIME = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8", ".css": "text/css",
        ".json": "application/json", ".f32": "application/octet-stream", ".glb": "model/gltf-binary",
        ".png": "image/png", ".exr": "image/x-exr", ".hdr": "image/vnd.radiance"}
_IMPORT = re.compile(r"""(?:from|import)\s*['"](\.{1,2}/[^'"]+)['"]""")
_IMPORTMAP = re.compile(r'<script type="importmap">(.*?)</script>', re.S)


VENDOR = Path(__file__).resolve().parent / "vendor" / "three"


def three_root() -> Path:
    """The three.js modules inside the package (``viewer/vendor/three``).

    The wheel carries them, copied at build time from the npm version the repository pins; a development checkout gets
    them from ``bash setup.sh``.

    Returns
    -------
    Path
        The folder (:data:`VENDOR`), holding ``build/three.module.js``.

    Raises
    ------
    LightprobeError
        The modules are not there.
    """
    if not (VENDOR / "build" / "three.module.js").is_file():
        raise LightprobeError(f"this installation lacks the viewer's three.js modules ({VENDOR}): install the "
                              "lightprobe wheel, or run 'bash setup.sh' in a checkout")
    return VENDOR


def module_files(root: Path) -> list[str]:
    """The three.js files the page needs: the entry modules and everything they import (relative imports).

    Parameters
    ----------
    root : Path
        The three.js folder (:func:`three_root`).

    Returns
    -------
    list of str
        Paths relative to ``root``, '/'-separated, sorted: :data:`ENTRY_MODULES` and every file reached from them by
        ``./`` or ``../`` imports that stays inside ``root`` and exists.
    """
    todo, seen = list(ENTRY_MODULES), set()
    while todo:
        rel = todo.pop()
        if rel in seen:
            continue
        seen.add(rel)
        text = (root / rel).read_text(encoding="utf-8")
        for spec in _IMPORT.findall(text):
            target = os.path.normpath(os.path.join(os.path.dirname(rel), spec)).replace(os.sep, "/")
            if not target.startswith("..") and (root / target).is_file():
                todo.append(target)
    return sorted(seen)


def page_html() -> tuple[str, str]:
    """The page and its Content-Security-Policy (the one inline script, the import map, allowed by its hash).

    Returns
    -------
    html : str
        ``static/index.html`` with its ``{{CSP}}`` placeholder filled in.
    csp : str
        The policy: nothing by default; scripts, connections, styles and images from the page's own origin only
        (images also ``data:`` and ``blob:``) and the import map by its SHA-256; no base URI, form action or framing.
    """
    template = (STATIC / "index.html").read_text(encoding="utf-8")
    match = _IMPORTMAP.search(template)
    digest = base64.b64encode(hashlib.sha256(match.group(1).encode()).digest()).decode()
    csp = (f"default-src 'none'; script-src 'self' 'sha256-{digest}'; connect-src 'self'; img-src 'self' data: "
           "blob:; style-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'")
    return template.replace("{{CSP}}", csp), csp


def safe_file(root: Path, rel: str) -> Path | None:
    """The regular file ``rel`` names inside ``root``, or None when it would leave the folder in any way.

    See the module docstring: no empty, ``.`` or ``..`` segment nor one starting with ``.``, no backslash or NUL, and
    a real path (symlinks followed) inside ``root``.

    Parameters
    ----------
    root : Path
        The folder served (the bake folder).
    rel : str
        The requested path below ``root``, already percent-decoded, '/'-separated.

    Returns
    -------
    Path or None
        The file's resolved real path, or None.
    """
    if not rel or "\x00" in rel or "\\" in rel:
        return None
    parts = rel.split("/")
    if any(not p or p in (".", "..") or p.startswith(".") for p in parts):
        return None
    base = root.resolve()
    try:
        real = base.joinpath(*parts).resolve(strict=True)
    except (OSError, RuntimeError):
        return None
    if base not in real.parents or not real.is_file():
        return None
    return real


class ViewServer:
    """Serves the page and one bake folder on 127.0.0.1 (``port`` 0: a free one) from a background thread.

    The server starts when the object is made; ``url`` is its address. A ``with`` block closes it on leaving.

    Parameters
    ----------
    bake : Path
        The bake folder (:func:`lightprobe.viewer.bake.bake`), served under ``/bake/``.
    port : int
        The TCP port on 127.0.0.1; 0 (default): a free one, then in ``address`` and ``url``.

    Raises
    ------
    LightprobeError
        The package lacks its three.js modules (:func:`three_root`).
    UsageError
        The port cannot be listened on.
    """

    def __init__(self, bake: Path, port: int = 0):
        self.bake = Path(bake).resolve()
        root = three_root()
        modules = {f"modules/three/{rel}": (root / rel).resolve() for rel in module_files(root)}
        statics = {f"static/{p.name}": p.resolve() for p in STATIC.iterdir() if p.is_file() and p.name != "index.html"}
        html, csp = page_html()
        fixed = {**modules, **statics}
        bake_root = self.bake

        class Handler(http.server.BaseHTTPRequestHandler):
            server_version = "lightprobe-view"
            sys_version = ""

            def _target(self):
                raw = self.path.split("?", 1)[0].split("#", 1)[0]
                if raw in ("/", "/index.html"):
                    return html.encode()
                rel = unquote(raw)
                if not rel.startswith("/"):
                    return None
                rel = rel[1:]
                if rel in fixed:
                    return fixed[rel]
                if rel.startswith("bake/"):
                    return safe_file(bake_root, rel[len("bake/"):])
                return None

            def _answer(self, body_too: bool) -> None:
                target = self._target()
                if target is None:
                    return self._status(404, "not found")
                if isinstance(target, bytes):
                    body, kind = target, MIME[".html"]
                else:
                    body, kind = target.read_bytes(), MIME.get(target.suffix.lower(), "application/octet-stream")
                self.send_response(200)
                self._headers(kind, len(body))
                if body_too:
                    self.wfile.write(body)

            def _headers(self, kind: str, length: int) -> None:
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(length))
                self.send_header("Content-Security-Policy", csp)
                self.send_header("X-Content-Type-Options", "nosniff")
                self.send_header("Referrer-Policy", "no-referrer")
                self.send_header("Cache-Control", "no-cache")
                self.end_headers()

            def _status(self, code: int, text: str, allow: bool = False) -> None:
                body = f"{code} {text}\n".encode()
                self.send_response(code)
                if allow:
                    self.send_header("Allow", "GET, HEAD")
                self._headers("text/plain; charset=utf-8", len(body))
                if self.command != "HEAD":
                    self.wfile.write(body)

            def do_GET(self):  # noqa: N802 - the standard library's names
                self._answer(True)

            def do_HEAD(self):  # noqa: N802
                self._answer(False)

            def _refuse(self):
                self._status(405, "method not allowed", allow=True)

            do_POST = do_PUT = do_DELETE = do_PATCH = do_OPTIONS = do_CONNECT = do_TRACE = _refuse

            def log_message(self, *args):
                pass

        try:
            self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", port), Handler)
        except OSError as e:
            raise UsageError(f"cannot listen on 127.0.0.1:{port}: {e.strerror or e}") from None
        self.httpd.daemon_threads = True
        self.address = self.httpd.server_address[:2]
        self.url = f"http://127.0.0.1:{self.address[1]}/"
        self._thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self._thread.start()

    def wait(self, stop: Callable[[], bool] = lambda: False) -> None:
        """Block until the server stops or ``stop()`` is true (asked every 0.1 s).

        Parameters
        ----------
        stop : callable
            Asked every 0.1 s; True ends the wait (``lightprobe view`` passes its Ctrl-C flag). Default: never.
        """
        while self._thread.is_alive() and not stop():
            self._thread.join(0.1)

    def close(self) -> None:
        """Stop serving and close the listening socket (what leaving a ``with`` block does)."""
        self.httpd.shutdown()
        self.httpd.server_close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def export_static(bake: Path, out: Path) -> Path:
    """Write the page, its modules and a copy of the bake into ``out`` (a new or empty folder), atomically.

    The tree is built in a temporary folder beside ``out`` (``.NAME.tmp-PID``) and renamed into place.

    Parameters
    ----------
    bake : Path
        The bake folder, copied whole into ``out/bake`` (symbolic links copied as the files they point to).
    out : Path
        The folder to write: new, or an empty folder.

    Returns
    -------
    Path
        ``out``, holding ``index.html``, ``static/``, ``modules/`` and ``bake/``.

    Raises
    ------
    UsageError
        ``out`` exists and is not an empty folder.
    LightprobeError
        The package lacks its three.js modules (:func:`three_root`).
    """
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise UsageError(f"{out} exists and is not empty: give a new or empty folder for --export")
    temp = out.parent / f".{out.name}.tmp-{os.getpid()}"
    shutil.rmtree(temp, ignore_errors=True)
    try:
        root = three_root()
        for rel in module_files(root):
            (temp / "modules" / "three" / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(root / rel, temp / "modules" / "three" / rel)
        (temp / "static").mkdir()
        for p in STATIC.iterdir():
            if p.is_file() and p.name != "index.html":
                shutil.copyfile(p, temp / "static" / p.name)
        shutil.copytree(bake, temp / "bake", symlinks=False)
        (temp / "index.html").write_text(page_html()[0], encoding="utf-8")
        if out.exists():
            out.rmdir()
        temp.rename(out)
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    return out
