import atexit
import glob
import importlib.util
import os
import shutil
import sys
import tempfile

import pytest

# One BLAS thread: the machine has two cores and numpy with two threads stalls.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
# Campaign results stores and calibration caches of the tests go to a fresh
# folder, never the user's (a stored run would be reused, not run).
os.environ["PROXOPS_CACHE"] = tempfile.mkdtemp(prefix="proxops-test-cache-")
atexit.register(shutil.rmtree, os.environ["PROXOPS_CACHE"], True)

# PROXOPS_BINDINGS_DIR=<cmake build>/python tests a freshly built module
# instead of the installed one (the editable install's import hook would
# otherwise win over PYTHONPATH).
_bindings_dir = os.environ.get("PROXOPS_BINDINGS_DIR")
if _bindings_dir:
    _found = glob.glob(os.path.join(_bindings_dir, "fsw_bindings*.so"))
    if not _found:
        raise RuntimeError(f"PROXOPS_BINDINGS_DIR={_bindings_dir}: no fsw_bindings module there")
    _spec = importlib.util.spec_from_file_location("fsw_bindings", _found[0])
    _mod = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(_mod)
    sys.modules["fsw_bindings"] = _mod


@pytest.fixture(scope="module")
def docking_log():
    """The bundled log as a valid docking log of the bench inspector (one
    whole-run segment; IMU, pose and valves): the base the user-mistake
    and hostile-input tests change one field of (copy it first)."""
    from bench.gap import bundled
    from bench.sim.flight_log import read_flight_log, validate_log
    from bench.sim.log_description import bench_description

    log = read_flight_log(bundled.LOG)
    whole_run = {"t_start_s": 0.0, "t_end_s": 120.05, "manoeuvre": "docking", "starts_at_rest": True}
    log.description = dict(bench_description(), segments=[whole_run])
    log.streams = {k: log.streams[k] for k in ("imu", "pose", "valves")}
    assert validate_log(log) == []
    return log
