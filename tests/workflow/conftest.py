"""Fixtures for the workflow tests: a real private single-node Slurm cluster."""

import pytest
from slurm_cluster import cluster_or_skip  # beside this file (pytest puts the folder on sys.path)


@pytest.fixture
def local_slurm(tmp_path_factory):
    """A running single-node Slurm cluster (``slurm_cluster.SlurmCluster``).

    Skips when the machine cannot host one (not root, no apt-get, foreign Slurm daemons,
    or BPMCAL_SKIP_SLURM=1). Installs slurmctld/slurmd/slurm-client/munge with apt-get if
    needed; the daemons are stopped when the test ends (or earlier by ``cluster.stop()``).
    """
    with cluster_or_skip(tmp_path_factory.mktemp("slurm_cluster")) as cluster:
        yield cluster
