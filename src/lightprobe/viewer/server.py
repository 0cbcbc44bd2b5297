"""The viewer's HTTP server and its static export: the page, its modules and one bake folder, nothing else.

Safety, because a local server is reachable by every page the user's browser opens: it binds 127.0.0.1 only,
answers GET and HEAD (any other method 405), lists no folder, and serves only

* ``/`` — the page (``index.html``, made from the template in ``static/`` with its Content-Security-Policy),
* ``/static/NAME`` — the page's own files (the files in ``static/``, fixed when the server starts),
* ``/modules/three/…`` — the three.js modules the page imports (the package's own copy, made at build time from
  the pinned npm package: a fixed list of files),
* ``/bake/…`` — regular files inside the bake folder, reached without ``..``, ``.``-prefixed or empty segments
  (after percent-decoding), backslashes or NUL, and whose real path (symlinks followed) stays inside the folder.

Everything else is 404. A request whose ``Host`` is not the address printed (``127.0.0.1``, ``localhost`` or
``[::1]`` with the served port) is 421 Misdirected Request, so a page on another origin that rebinds its DNS name
to 127.0.0.1 reads nothing. Every answer — the standard library's own errors (400, 501, 505 …) included — carries
the CSP, ``nosniff`` and a MIME type from :data:`MIME`.

One client cannot starve the server: at most :data:`MAX_CONNECTIONS` connections are served at once (one request
each); a connection over the limit waits for a free slot in the listen queue, and is closed if none frees within
the idle timeout. A connection silent for :data:`IDLE_TIMEOUT` seconds is closed, and so is one that has not sent
a whole request line and headers within :data:`REQUEST_DEADLINE` seconds, however it spaces its bytes. Files are
streamed in chunks of :data:`CHUNK` bytes; a client's fault (a reset, a broken pipe, a timeout) prints nothing.

The static export writes the same tree (``index.html``, ``static/``, ``modules/``, ``bake/``) into a folder, so the
page is the same file whether served here or from any static host.
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import http.server
import os
import re
import shutil
import socket
import stat
import sys
import threading
import warnings
from collections.abc import Callable
from pathlib import Path
from urllib.parse import unquote

from ..util.errors import LightprobeError, LightprobeWarning, UsageError

STATIC = Path(__file__).resolve().parent / "static"
ENTRY_MODULES = ("build/three.module.js", "examples/jsm/controls/OrbitControls.js",
                 "examples/jsm/loaders/GLTFLoader.js")
MIME = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8", ".css": "text/css",
        ".json": "application/json", ".f32": "application/octet-stream", ".glb": "model/gltf-binary",
        ".png": "image/png", ".exr": "image/x-exr", ".hdr": "image/vnd.radiance"}
_IMPORT = re.compile(r"""(?:from|import)\s*['"](\.{1,2}/[^'"]+)['"]""")
_IMPORTMAP = re.compile(r'<script type="importmap">(.*?)</script>', re.S)
MAX_CONNECTIONS = 32   # served at once: a page loads its ~40 files over a handful of connections
IDLE_TIMEOUT = 5.0     # seconds a connection may stay silent (reading the request, or the client not reading)
REQUEST_DEADLINE = 10.0  # seconds to send a whole request line and headers: a client dripping bytes is never idle
CHUNK = 1 << 16        # bytes read from a file and sent at a time
# A client's fault, not the server's: nothing to print.
_CLIENT_FAULTS = (ConnectionError, TimeoutError)


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


def allowed_hosts(port: int) -> frozenset[str]:
    """The ``Host`` header values the server answers: the loopback names with ``port``, lower case.

    Parameters
    ----------
    port : int
        The port served.

    Returns
    -------
    frozenset of str
        ``127.0.0.1:PORT``, ``localhost:PORT`` and ``[::1]:PORT``; for port 80 also the names without a port (what
        a browser sends there).
    """
    names = ("127.0.0.1", "localhost", "[::1]")
    return frozenset(f"{n}:{port}" for n in names) | (frozenset(names) if port == 80 else frozenset())


class _BoundedServer(http.server.ThreadingHTTPServer):
    """A threading HTTP server with at most ``limit`` connections at once, each timing out after ``timeout`` s idle,
    and no traceback for a client's fault."""

    daemon_threads = True
    request_queue_size = 64

    def __init__(self, address, handler, limit: int, timeout: float):
        self.slots = threading.BoundedSemaphore(limit)
        self.idle_timeout = timeout
        self.closing = threading.Event()
        super().__init__(address, handler)

    def process_request(self, request, client_address):
        # Over the limit the accepting thread waits for a slot (later clients wait in the listen queue, the
        # kernel's bound), asking every 0.1 s whether the server is closing; a slot frees within the idle timeout
        # unless every served client is busy, and then this connection is closed rather than waited on for ever.
        waited = 0.0
        while not self.slots.acquire(timeout=0.1):
            waited += 0.1
            if self.closing.is_set() or waited >= self.idle_timeout:
                self.shutdown_request(request)
                return
        try:
            request.settimeout(self.idle_timeout)
            super().process_request(request, client_address)
        except BaseException:
            self.slots.release()
            self.shutdown_request(request)
            raise

    def process_request_thread(self, request, client_address):
        try:
            super().process_request_thread(request, client_address)
        finally:
            self.slots.release()

    def handle_error(self, request, client_address):
        if isinstance(sys.exc_info()[1], _CLIENT_FAULTS):
            return
        super().handle_error(request, client_address)


class ViewServer:
    """Serves the page and one bake folder on 127.0.0.1 (``port`` 0: a free one) from a background thread.

    The server starts when the object is made; ``url`` is its address. A ``with`` block closes it on leaving.

    Parameters
    ----------
    bake : Path
        The bake folder (:func:`lightprobe.viewer.bake.bake`), served under ``/bake/``.
    port : int
        The TCP port on 127.0.0.1; 0 (default): a free one, then in ``address`` and ``url``.
    max_connections : int
        Connections served at once. Default :data:`MAX_CONNECTIONS`.
    idle_timeout : float
        Seconds a connection may stay silent before it is closed. Default :data:`IDLE_TIMEOUT`.
    request_deadline : float
        Seconds a client has to send a request's line and headers, however it spaces its bytes; then the connection
        is closed. Default :data:`REQUEST_DEADLINE`.

    Raises
    ------
    LightprobeError
        The package lacks its three.js modules (:func:`three_root`).
    UsageError
        The port cannot be listened on.
    """

    def __init__(self, bake: Path, port: int = 0, max_connections: int = MAX_CONNECTIONS,
                 idle_timeout: float = IDLE_TIMEOUT, request_deadline: float = REQUEST_DEADLINE):
        self.bake = Path(bake).resolve()
        root = three_root()
        modules = {f"modules/three/{rel}": (root / rel).resolve() for rel in module_files(root)}
        statics = {f"static/{p.name}": p.resolve() for p in STATIC.iterdir() if p.is_file() and p.name != "index.html"}
        html, csp = page_html()
        fixed = {**modules, **statics}
        bake_root = self.bake
        hosts: frozenset[str] = frozenset()  # set once the port is known

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

            def handle_one_request(self) -> None:
                # the idle timeout bounds each silence, not a request sent a byte at a time: the request's line
                # and headers get one deadline, past which the socket is shut and this thread ends on it
                self._deadline = threading.Timer(request_deadline, self._cut)
                self._deadline.daemon = True
                self._deadline.start()
                try:
                    super().handle_one_request()
                finally:
                    self._deadline.cancel()

            def _cut(self) -> None:
                with contextlib.suppress(OSError):
                    self.connection.shutdown(socket.SHUT_RDWR)

            def parse_request(self) -> bool:
                ok = super().parse_request()
                self._deadline.cancel()  # the headers are in: the response is bounded by the idle timeout alone
                if not ok:
                    return False
                if self.headers.get("Host", "").strip().lower() not in hosts:
                    self._status(421, "misdirected request: this server answers only at the address it printed")
                    return False
                return True

            def _answer(self, body_too: bool) -> None:
                if self.request_version == "HTTP/0.9":  # it has no headers to carry the CSP
                    return self._status(400, "bad request: HTTP/0.9")
                target = self._target()
                if isinstance(target, bytes):
                    self.send_response(200)
                    self._headers(MIME[".html"], len(target))
                    if body_too:
                        self.wfile.write(target)
                    return
                try:
                    file = open(target, "rb") if target is not None else None
                except OSError:  # gone since it was found
                    file = None
                if file is None:
                    return self._status(404, "not found")
                with file:
                    self.send_response(200)
                    self._headers(MIME.get(target.suffix.lower(), "application/octet-stream"),
                                  os.fstat(file.fileno()).st_size)
                    if body_too:
                        shutil.copyfileobj(file, self.wfile, CHUNK)

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
                self.close_connection = True
                if self.request_version == "HTTP/0.9":  # headers are written for HTTP/1.0 and later only
                    self.request_version = "HTTP/1.0"
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

            def send_error(self, code, message=None, explain=None):
                # The standard library's own error page (malformed request, unknown method, …): the same headers.
                self._status(code, (message or self.responses.get(code, ("error",))[0]).lower())

            do_POST = do_PUT = do_DELETE = do_PATCH = do_OPTIONS = do_CONNECT = do_TRACE = _refuse

            def log_message(self, *args):
                pass

        try:
            self.httpd = _BoundedServer(("127.0.0.1", port), Handler, max_connections, idle_timeout)
        except OSError as e:
            raise UsageError(f"cannot listen on 127.0.0.1:{port}: {e.strerror or e}") from None
        self.address = self.httpd.server_address[:2]
        hosts = allowed_hosts(self.address[1])
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
        self.httpd.closing.set()
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
        The bake folder, copied into ``out/bake``: its regular files and folders only, by the rule the server serves
        by — a symbolic link, a name starting with ``.`` or anything else (a FIFO, a device) is left out, and a
        :class:`~lightprobe.util.errors.LightprobeWarning` names how many.
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

    Warns
    -----
    LightprobeWarning
        Entries of the bake folder were left out (see ``bake``).
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
        left_out = _copy_regular(Path(bake), temp / "bake")
        (temp / "index.html").write_text(page_html()[0], encoding="utf-8")
        if out.exists():
            out.rmdir()
        temp.rename(out)
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    if left_out:
        warnings.warn(LightprobeWarning(f"--export left out {len(left_out)} entries of the bake folder that are not "
                                        f"regular files or folders (symbolic links, hidden names …), e.g. "
                                        f"{left_out[0]}"), stacklevel=2)
    return out


def _copy_regular(source: Path, target: Path) -> list[str]:
    """Copy the regular files and folders under ``source`` into the new folder ``target``, never following a link;
    the names left out (relative to ``source``) are returned."""
    target.mkdir()
    left_out = []
    for entry in sorted(os.scandir(source), key=lambda e: e.name):
        mode = entry.stat(follow_symlinks=False).st_mode
        if entry.name.startswith(".") or not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
            left_out.append(entry.name)
        elif stat.S_ISDIR(mode):
            left_out += [f"{entry.name}/{rel}" for rel in _copy_regular(Path(entry.path), target / entry.name)]
        else:
            _copy_file(Path(entry.path), target / entry.name)
    return left_out


def _copy_file(source: Path, target: Path) -> None:
    """Copy one regular file, opened without following a link or waiting on a FIFO: one swapped in since the folder
    was listed is refused."""
    changed = LightprobeError(f"{source} changed while the bake was exported: export again")
    try:
        fd = os.open(source, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        raise changed from None
    with open(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise changed
        with open(target, "xb") as g:
            shutil.copyfileobj(f, g, CHUNK)
