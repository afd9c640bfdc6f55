"""The fast tier stays fast: a test module that starts nodes over DDS, brings the system up or
starts a Dask cluster is in the slow tier (conftest.SLOW_MODULES)."""
from pathlib import Path

from conftest import SLOW_MODULES

TEST_DIR = Path(__file__).resolve().parent
#: What a module does when it uses DDS or a cluster.
SLOW_SIGNS = ('ros_context(', 'run_bringup(', 'LocalCluster(', 'start_node(', 'SensorReplayer(')


def test_modules_that_use_dds_or_a_cluster_are_in_the_slow_tier():
    # test_nodes_support holds the helpers (ros_context), no test.
    missing = sorted(p.stem for p in TEST_DIR.glob('test_*.py')
                     if p.stem not in SLOW_MODULES | {'test_nodes_support', 'test_tiers'}
                     and any(s in p.read_text() for s in SLOW_SIGNS))
    assert not missing, f'add to conftest.SLOW_MODULES: {missing}'


def test_every_slow_module_exists():
    assert sorted(m for m in SLOW_MODULES if not (TEST_DIR / f'{m}.py').exists()) == []
