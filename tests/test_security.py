"""Security: who can reach what a batch or the viewer starts.

A ``--dask-local`` cluster takes work only from a client holding the credentials made for its run; ``view`` answers
only at the address it printed, with its security headers on every answer, stays available to a normal request
while more idle clients than its limit are connected, and its static export carries only the bake's regular files.
"""

from __future__ import annotations

import http.client
import os
import socket
import struct
import time
import warnings

import numpy as np
import pytest

from lightprobe.maps.images import write_image
from lightprobe.util.errors import LightprobeWarning, UsageError
from lightprobe.viewer.server import ViewServer, export_static

DRIP_SECONDS = 15.0  # how long the dripping client keeps going: ten times the deadline it is given
DEADLINE = 60.0  # seconds: generous for a loaded two-core machine; the tests assert behaviour, not speed


# ---- batch --dask-local ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dask_pool():
    from lightprobe.batch.runner import DaskPool

    pool = DaskPool(local=1, timeout=DEADLINE)
    yield pool
    pool.close()


def test_dask_local_cluster_refuses_a_client_without_its_credentials(dask_pool, tmp_path):
    from dask.distributed import Client
    from distributed.security import Security

    from lightprobe.batch.runner import run_batch
    from lightprobe.batch.task import JobOptions

    inputs = [str(write_image(tmp_path / f"p{i}.exr", np.full((8, 16, 3), i + 1.0, np.float32))) for i in range(2)]
    summary = run_batch(inputs, tmp_path / "out", JobOptions(jobs=("sh",)), dask_pool)
    assert summary.done == 2 and summary.failed == 0  # the batch's own client, holding the credentials, works

    address = dask_pool.cluster.scheduler_address
    planted = tmp_path / "ran"

    def payload():
        planted.write_text("code of a stranger ran as the batch's user")

    for scheme, security in (("tcp://", None), ("tls://", Security.temporary())):  # none, or credentials of its own
        start = time.monotonic()
        with (pytest.raises(Exception),  # noqa: B017 - refused in whichever way Dask reports it
              Client(scheme + address.split("://", 1)[1], timeout="10s", security=security) as stranger):
            stranger.submit(payload, pure=False).result(timeout=10)
        assert time.monotonic() - start < DEADLINE
    assert not planted.exists()


def test_dask_local_cluster_listens_only_for_tls_and_serves_no_dashboard(dask_pool):
    """Every port the cluster's processes (this one, its nannies and workers) listen on is one of its TLS addresses:
    no dashboard, no status pages, no metrics over plain HTTP."""
    import psutil

    info = dask_pool.client.scheduler_info()
    addresses = {dask_pool.cluster.scheduler_address, *info["workers"], *(w["nanny"] for w in info["workers"].values())}
    assert all(a.startswith("tls://127.0.0.1:") for a in addresses), addresses
    tls_ports = {int(a.rsplit(":", 1)[1]) for a in addresses}
    me = psutil.Process()
    listening = {(c.laddr.ip, c.laddr.port) for proc in (me, *me.children(recursive=True))
                 for c in proc.net_connections("tcp") if c.status == psutil.CONN_LISTEN}
    assert {port for _, port in listening} == tls_ports, (listening, tls_ports)
    assert {ip for ip, _ in listening} == {"127.0.0.1"}
    assert dask_pool.dashboard is None


def test_a_tls_scheduler_is_reached_with_the_tls_settings_of_dasks_configuration(dask_pool, tmp_path):
    import dask

    from lightprobe.batch.runner import DaskPool

    security, address = dask_pool.cluster.security, dask_pool.cluster.scheduler_address
    files = {}
    for key, pem in (("ca-file", security.tls_ca_file), ("client.cert", security.tls_client_cert),
                     ("client.key", security.tls_client_key)):
        files[f"distributed.comm.tls.{key}"] = str(tmp_path / key)
        (tmp_path / key).write_text(pem)
    with pytest.raises(UsageError, match="cannot reach the Dask scheduler"):
        DaskPool(address, timeout=5)
    with dask.config.set(files):
        pool = DaskPool(address, timeout=DEADLINE)
        try:
            assert pool.client.submit(sum, [1, 2], pure=False).result(timeout=DEADLINE) == 3
        finally:
            pool.close()


# ---- view: hosts and headers ----------------------------------------------------------------------------------------
@pytest.fixture
def bake_dir(tmp_path):
    folder = tmp_path / "bake"
    folder.mkdir()
    (folder / "bake.json").write_text("{}")
    return folder


def raw(server: ViewServer, data: bytes) -> tuple[int, dict[str, str], bytes]:
    """Send ``data`` as it is and read the answer to its end: status, headers (lower-case names), body."""
    with socket.create_connection(server.address, timeout=DEADLINE) as s:
        s.sendall(data)
        answer = b""
        while chunk := s.recv(65536):
            answer += chunk
    head, _, body = answer.partition(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    headers = {k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in lines[1:])}
    return int(lines[0].split()[1]), headers, body


def assert_security_headers(headers: dict[str, str]) -> None:
    assert "default-src 'none'" in headers.get("content-security-policy", ""), headers
    assert headers.get("x-content-type-options") == "nosniff" and headers.get("referrer-policy") == "no-referrer"


@pytest.mark.parametrize("host", ["attacker.example:{port}", "attacker.example", "127.0.0.1:{other}", "127.0.0.1",
                                  "localhost", "127.0.0.1:{port}.attacker.example", "127.0.0.2:{port}", "",
                                  None])
def test_view_refuses_a_request_for_another_host(bake_dir, host):
    with ViewServer(bake_dir) as server:
        port = server.address[1]
        line = "" if host is None else f"Host: {host.format(port=port, other=port + 1)}\r\n"
        for method in ("GET", "HEAD", "POST"):
            status, headers, body = raw(server, f"{method} /bake/bake.json HTTP/1.1\r\n{line}\r\n".encode())
            assert status == 421 and b"{}" not in body, (method, host, status)
            assert_security_headers(headers)


@pytest.mark.parametrize("host", ["127.0.0.1:{port}", "localhost:{port}", "[::1]:{port}", "LocalHost:{port}"])
def test_view_answers_at_the_address_it_printed(bake_dir, host):
    with ViewServer(bake_dir) as server:
        status, headers, body = raw(server, f"GET /bake/bake.json HTTP/1.1\r\nHost: "
                                            f"{host.format(port=server.address[1])}\r\n\r\n".encode())
        assert status == 200 and body == b"{}"
        assert_security_headers(headers)


@pytest.mark.parametrize("request_line, code", [
    ("BREW /bake/bake.json HTTP/1.1", 501), ("GET /bake/bake.json HTTP/2.5", 505), ("GET", 400),
    ("GET /bake/bake.json HTTP/x", 400), ("GET /bake/bake.json", 400), ("GET /nothing HTTP/1.1", 404)])
def test_view_error_pages_carry_the_same_security_headers(bake_dir, request_line, code):
    with ViewServer(bake_dir) as server:
        status, headers, body = raw(server, f"{request_line}\r\nHost: 127.0.0.1:{server.address[1]}\r\n\r\n".encode())
        assert status == code, (request_line, status)
        assert_security_headers(headers)
        assert headers["content-type"].startswith("text/plain") and b"<" not in body


# ---- view: one client cannot starve it ------------------------------------------------------------------------------
def wait_closed(sock: socket.socket) -> bool:
    """True once the server closes ``sock`` (EOF or reset), False if it is still open at the deadline."""
    sock.settimeout(DEADLINE)
    try:
        return sock.recv(1) == b""
    except ConnectionResetError:
        return True
    except TimeoutError:
        return False


def test_view_closes_an_idle_connection_after_its_timeout(bake_dir):
    with ViewServer(bake_dir, idle_timeout=0.5) as server:
        with socket.create_connection(server.address, timeout=DEADLINE) as silent:
            assert wait_closed(silent)
        with socket.create_connection(server.address, timeout=DEADLINE) as halfway:
            halfway.sendall(b"GET /bake/bake.json HTTP/1.1\r\nHost: ")
            assert wait_closed(halfway)


def test_view_closes_a_connection_that_drips_its_request_past_the_deadline(bake_dir):
    """A byte every 0.2 s keeps a connection from ever being idle for its 1 s timeout; the request's line and headers
    still have one deadline (1.5 s here), so the server closes it while it is still dripping."""
    import select

    with ViewServer(bake_dir, idle_timeout=1.0, request_deadline=1.5) as server:
        with socket.create_connection(server.address, timeout=DEADLINE) as drip:
            drip.sendall(b"GET /bake/bake.json HTTP/1.1\r\nX-Slow: ")
            start, closed = time.monotonic(), False
            while not closed and time.monotonic() - start < DRIP_SECONDS:
                try:
                    drip.sendall(b"a")
                    if select.select([drip], [], [], 0.2)[0]:
                        closed = drip.recv(1) == b""
                except OSError:
                    closed = True
            assert closed, f"still open after {DRIP_SECONDS} s of dripping"


def test_view_serves_a_request_while_more_idle_clients_than_its_limit_are_connected(bake_dir, capfd):
    (bake_dir / "big.f32").write_bytes(os.urandom(1 << 23))  # more than the socket buffers hold
    with ViewServer(bake_dir, max_connections=4, idle_timeout=1.0) as server:
        host = f"Host: 127.0.0.1:{server.address[1]}\r\n\r\n".encode()
        idle = [socket.create_connection(server.address, timeout=DEADLINE) for _ in range(12)]
        rude = []  # clients that ask for a big file and reset the connection instead of reading it
        for _ in range(4):
            s = socket.create_connection(server.address, timeout=DEADLINE)
            s.sendall(b"GET /bake/big.f32 HTTP/1.1\r\n" + host)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            rude.append(s)
        for s in rude:
            s.close()
        try:
            conn = http.client.HTTPConnection(*server.address, timeout=DEADLINE)
            conn.request("GET", "/bake/bake.json")
            res = conn.getresponse()
            assert res.status == 200 and res.read() == b"{}"
            conn.close()
            assert all(wait_closed(s) for s in idle)
        finally:
            for s in idle:
                s.close()
    err = capfd.readouterr().err
    assert "Traceback" not in err and "Exception" not in err, err[-3000:]


# ---- view --export --------------------------------------------------------------------------------------------------
def test_view_export_copies_no_file_a_symlink_in_the_bake_points_at(bake_dir, tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("lightprobe-test-secret")
    (tmp_path / "private").mkdir()
    (tmp_path / "private" / "notes.txt").write_text("lightprobe-test-secret")
    (bake_dir / "maps").mkdir()
    (bake_dir / "maps" / "a.f32").write_bytes(b"\0" * 8)
    (bake_dir / "background.png").symlink_to(secret)
    (bake_dir / "maps" / "b.f32").symlink_to(secret)
    (bake_dir / "linked").symlink_to(tmp_path / "private")
    os.mkfifo(bake_dir / "pipe")
    with pytest.warns(LightprobeWarning, match="left out 4 entries"):
        export_static(bake_dir, tmp_path / "site")
    site = tmp_path / "site"
    files = sorted(str(p.relative_to(site / "bake")) for p in (site / "bake").rglob("*"))
    assert files == ["bake.json", "maps", "maps/a.f32"]
    for p in site.rglob("*"):
        assert not p.is_symlink() and (p.is_dir() or b"lightprobe-test-secret" not in p.read_bytes()), p
    (bake_dir / "maps" / "b.f32").unlink()
    for p in ("background.png", "linked", "pipe"):
        (bake_dir / p).unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a bake of regular files only: exported whole, nothing said
        export_static(bake_dir, tmp_path / "site2")
    assert (tmp_path / "site2" / "bake" / "maps" / "a.f32").read_bytes() == b"\0" * 8
