"""The same study on a Dask LocalCluster on loopback gives exactly the local table for the same seed; a scheduler
that never answers and a cluster without workers end in one stated error, not a silent wait."""

from __future__ import annotations

import socket
import threading

import pytest

from impactometer.errors import ParameterError, SimulationError
from impactometer.studies import StudyOptions, executors, run_study

distributed = pytest.importorskip("dask.distributed", reason="Dask distributed is the optional extra [dask]")


def test_dask_cluster_matches_local_run(tmp_path):
    options = StudyOptions(grid=3, seed=11, params={"peak-force.chunk_size": 5})
    local = run_study("peak-force", tmp_path / "local", options, workers=1)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        remote = run_study("peak-force", tmp_path / "dask", options, scheduler=cluster.scheduler_address)
    assert remote.chunks == local.chunks == 6
    assert remote.table.read_text() == local.table.read_text()


def test_unreachable_scheduler_is_a_parameter_error(tmp_path):
    with pytest.raises(ParameterError, match="--scheduler: cannot connect to 'tcp://127.0.0.1:9'"):
        run_study("peak-force", tmp_path, StudyOptions(grid=2), scheduler="tcp://127.0.0.1:9")


@pytest.fixture(params=["silent", "http"])
def not_a_scheduler(request):
    """A loopback listener that accepts connections and then stays silent, or answers as a web server would."""
    server = socket.create_server(("127.0.0.1", 0))
    accepted, stop = [], threading.Event()

    def serve():
        server.settimeout(0.1)
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            accepted.append(conn)
            if request.param == "http":
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    stop.set()
    thread.join()
    for conn in accepted:
        conn.close()
    server.close()


def test_a_listener_that_is_no_scheduler_is_refused_in_one_line(not_a_scheduler):
    with pytest.raises(ParameterError, match="--scheduler: .*(sent no Dask handshake within 1 s|not as a Dask sch)"):
        executors.connect(not_a_scheduler, deadline=1.0)


def test_a_cluster_without_workers_is_said_and_given_up(tmp_path, monkeypatch):
    monkeypatch.setattr(executors, "NO_WORKER_DEADLINE", 1.0)
    said = []
    with distributed.LocalCluster(n_workers=0, processes=True, host="127.0.0.1", dashboard_address=None) as cluster, \
            pytest.raises(SimulationError, match="no Dask worker has been alive .* finished chunks are kept"):
        run_study("peak-force", tmp_path, StudyOptions(grid=2), scheduler=cluster.scheduler_address,
                  status=lambda name, text: said.append(text))
    assert any(text.startswith("no Dask worker is alive") for text in said)
