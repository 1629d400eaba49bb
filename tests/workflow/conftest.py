"""Fixtures for the workflow tests: a real private single-node Slurm cluster."""

import pytest
from support.slurm_cluster import cluster_or_skip


@pytest.fixture
def local_slurm(tmp_path_factory):
    """A running single-node Slurm cluster (``slurm_cluster.SlurmCluster``).

    Skips unless asked for with BPMCAL_TEST_SLURM=1, and when the machine cannot host
    one (not root, no apt-get, foreign Slurm daemons). Installs
    slurmctld/slurmd/slurm-client/munge with apt-get if needed; the daemons are stopped
    when the test ends (or earlier by ``cluster.stop()``).
    """
    with cluster_or_skip(tmp_path_factory.mktemp("slurm_cluster")) as cluster:
        yield cluster
