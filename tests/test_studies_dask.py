"""The same study on a Dask LocalCluster on loopback gives exactly the local table for the same seed."""

from __future__ import annotations

import pytest

from impactometer.errors import ParameterError
from impactometer.studies import StudyOptions, run_study

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
