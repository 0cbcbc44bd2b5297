"""Security: who can reach what a batch or the viewer starts.

A ``--dask-local`` cluster takes work only from a client holding the credentials made for its run; ``view`` answers
only at the address it printed, with its security headers on every answer, stays available to a normal request
while more idle clients than its limit are connected, and its static export carries only the bake's regular files.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from lightprobe.maps.images import write_image
from lightprobe.util.errors import UsageError

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
        with pytest.raises(Exception):  # noqa: B017 - refused in whichever way Dask reports it
            with Client(scheme + address.split("://", 1)[1], timeout="10s", security=security) as stranger:
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
