"""What starting viz3d imports (issue 14): the command line and the package load no viewer, recorder,
plotting, study or mesh library, and a headless run of a small scene loads none of them either, nor
the parts of scipy it does not use, and loading its compiled kernel from numba's cache does not set up
what numba needs only to compile. Checked on ``sys.modules`` of a fresh interpreter, not by timing
(``benchmarks/bench_startup.py`` measures the time).
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Imported only by the commands that use them: viewer, recorder, charts, studies, meshes, oracles.
OPTIONAL = ("viser", "rerun", "matplotlib", "dask", "distributed", "trimesh", "coal", "pyarrow", "sympy", "websockets")
#: Parts of scipy a rigid multibody run does not need (each costs 0.1-0.4 s to import; scipy.sparse came
#: with the row ordering's reverse Cuthill-McKee, now viz3d's own).
UNUSED_SCIPY = ("scipy.sparse", "scipy.optimize", "scipy.integrate", "scipy.special", "scipy.fft", "scipy.spatial",
                "scipy.stats")
#: The modules of the other kinds of scene (a multibody scene's run needs none of them).
OTHER_KINDS = ("viz3d.hydro", "viz3d.scene.hydro")
#: Imported by numba's target refresh (the typing and lowering of all numba supports), which compiling
#: needs and loading viz3d's kernel from the cache does not (``viz3d.compiled.LoadingCache``); and
#: ``numba.np.arrayobj`` (33 ms), the module of an implementation the kernel inlines, which unpickling
#: its environment imported (``LoadingCache``'s environments of modules not imported).
NUMBA_TARGET = ("numba.np.linalg", "numba.np.arraymath", "numba.typed.typeddict", "numba.np.random.generator_core",
                "numba.np.arrayobj")


def loaded_after(code: str) -> set[str]:
    """The top-level and scipy modules in ``sys.modules`` after running ``code`` in a fresh interpreter."""
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=600, check=True)
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


def offending(modules: set[str], names: tuple[str, ...]) -> list[str]:
    return sorted(n for n in names if n in modules)


def modules_of_a_warm_run(tmp_path, scene: str = "heavy_top") -> set[str]:
    """``loaded_after`` a headless run of ``scene`` (the heavy top) whose kernel came from numba's cache (a
    first run warms it, compiling the kernel if it is cold, and the mesh properties' disk cache)."""
    pytest.importorskip("numba")
    out = tmp_path / "top.npz"
    run = ("from viz3d.cli import main\n"
           f"assert main(['run', 'scenes/{scene}.toml', '--t-end', '0.01', '--out', {str(out)!r}, '--no-progress']) == 0\n")
    loaded_after(run)
    return loaded_after(run + "from viz3d.kernel import stepping\n"
                              "assert stepping.advance_frames.stats.cache_hits, 'the kernel was compiled, not loaded'")


@pytest.mark.parametrize("code", ["import viz3d", "import viz3d.cli", "from viz3d.cli import main"])
def test_the_package_and_the_command_line_import_no_optional_library(code):
    modules = loaded_after(code)
    assert not offending(modules, OPTIONAL + ("scipy", "numba")), code


def test_the_lazy_api_gives_the_entry_points():
    modules = loaded_after("import viz3d\nassert callable(viz3d.simulate) and callable(viz3d.load_scene)\n"
                           "import viz3d.simulate\nassert callable(viz3d.simulate), viz3d.simulate")
    assert "viz3d.simulate" in modules


def test_a_headless_run_imports_only_what_it_uses(tmp_path):
    out = tmp_path / "top.npz"
    code = ("from viz3d.cli import main\n"
            f"assert main(['run', 'scenes/heavy_top.toml', '--t-end', '0.01', '--out', {str(out)!r}, '--no-progress']) == 0")
    modules = loaded_after(code)
    assert not offending(modules, OPTIONAL + UNUSED_SCIPY + OTHER_KINDS)
    assert out.exists()


def test_check_builds_without_the_compiled_kernel():
    """``viz3d check`` builds its scenes on the NumPy path: no kernel module is imported, so no compiled
    entry is loaded from numba's cache, nor compiled (minutes) on a cold one, to check a scene."""
    modules = loaded_after("from viz3d.cli import main\nassert main(['check', 'scenes/heavy_top.toml']) == 0")
    assert "viz3d.scene.build" in modules
    assert not sorted(m for m in modules if m.startswith("viz3d.kernel"))


def test_a_warm_run_loads_its_kernel_without_numbas_target_refresh(tmp_path):
    modules = modules_of_a_warm_run(tmp_path)
    assert not offending(modules, NUMBA_TARGET)


#: What a warm run of a rigid scene on fixed steps imports none of: ``numpy.ma`` (numba's typing of an
#: array asks whether it is masked: ``viz3d.kernel._argument_type`` types the kernel's arguments without
#: it), ALI3-P, the compiled adaptive driver, the shape contacts, the contact report, the flexible
#: bars' mode sets, planar elements and mode selection, and water.
NOT_IN_A_RIGID_RUN = ("numpy.ma", "viz3d.ali3p", "viz3d.kernel.adaptive", "viz3d.kernel.ali3p", "viz3d.kernel.collisions",
                      "viz3d.contact.collision", "viz3d.contact.narrowphase", "viz3d.scene.collisions",
                      "viz3d.contact.report", "viz3d.flexible.modes", "viz3d.flexible.planar", "viz3d.flexible.selection",
                      "viz3d.water")


def test_a_warm_rigid_run_imports_nothing_its_scene_does_not_use(tmp_path):
    modules = modules_of_a_warm_run(tmp_path)
    assert not offending(modules, NOT_IN_A_RIGID_RUN)


def test_a_warm_run_of_a_mesh_body_imports_no_mesh_library(tmp_path):
    """The torque-free T-handle's mass properties come from its mesh file: computed once (trimesh, and
    with it scipy.spatial, scipy.sparse and scipy.optimize), then read from the disk cache."""
    modules = modules_of_a_warm_run(tmp_path, "torque_free")
    assert not offending(modules, ("trimesh",) + UNUSED_SCIPY + NOT_IN_A_RIGID_RUN)


def test_reading_a_cache_index_imports_no_module_of_the_other_signatures(tmp_path):
    """numba's cache index of a function holds every signature it was compiled for, and reading it to
    find one imported the module of every class in all of them (the kernel's, cached for systems with
    shape contacts, imported the narrow phase into rigid runs). A function cached for an array and
    for a named tuple of another module is loaded, for the array, from a fresh process that does not
    import that module: the entry is a cache hit, and the module stays unimported."""
    pytest.importorskip("numba")
    (tmp_path / "probe_pair.py").write_text("from typing import NamedTuple\n\nimport numpy as np\n\n\n"
                                            "class Pair(NamedTuple):\n    a: np.ndarray\n    b: np.ndarray\n")
    (tmp_path / "probe_fn.py").write_text("from viz3d.compiled import entry\n\n\n@entry\ndef second(x, y):\n"
                                          "    return y\n")
    env = {**__import__("os").environ, "PYTHONPATH": f"{tmp_path}{__import__('os').pathsep}{ROOT}"}

    def probe(code: str) -> list[str]:
        out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                             timeout=600, check=True)
        return out.stdout.split()

    probe("import numpy as np\nfrom probe_fn import second\nfrom probe_pair import Pair\n"
          "assert second(Pair(np.zeros(2), np.ones(2)), 1.0) == 1.0 and second(np.zeros(2), 2.0) == 2.0\n"
          "assert len(second.overloads) == 2")
    seen = probe("import sys\nimport numpy as np\nfrom probe_fn import second\n"
                 "assert second(np.zeros(3), 3.0) == 3.0\n"
                 "print(sum(second.stats.cache_hits.values()), 'probe_pair' in sys.modules)")
    assert seen == ["1", "False"]


def test_a_warm_rigid_run_imports_no_scipy_linalg(tmp_path):
    """A run the kernel covers projects its initial state there (``scene.build.kernel_projection``), not
    with LAPACK's ``dposv`` (``viz3d.constraints.schur_solve``): with numba's cache warm, nothing imports
    scipy.linalg (compiling, on a cold cache, does: numba's target refresh imports it)."""
    modules = modules_of_a_warm_run(tmp_path)
    assert not offending(modules, ("scipy.linalg", "scipy.linalg.lapack", "scipy.linalg.cython_lapack"))


def test_a_warm_rigid_run_loads_one_compiled_entry(tmp_path):
    """Each compiled entry loaded from numba's cache costs a run's start tens of milliseconds (its
    library carries its own copy of the vector field): a covered rigid run's initial projection, steps
    and output samples all go through ``advance_frames``, the one entry it loads."""
    pytest.importorskip("numba")
    out = tmp_path / "top.npz"
    run = ("from viz3d.cli import main\n"
           f"assert main(['run', 'scenes/heavy_top.toml', '--t-end', '0.01', '--out', {str(out)!r}, '--no-progress']) == 0\n")
    loaded_after(run)  # warms numba's cache
    probe = (run + "import sys\nfrom numba.core.registry import CPUDispatcher\n"
             "entries = sorted({d.py_func.__qualname__ for name, mod in list(sys.modules.items()) if name.startswith('viz3d')"
             " for d in vars(mod).values() if isinstance(d, CPUDispatcher) and d.overloads"
             " and not d.targetoptions.get('no_cpython_wrapper')})\n"
             "print(entries)\n"
             "assert entries == ['advance_frames'], entries\n")
    loaded_after(probe)


def test_the_compiled_kernel_needs_no_lapack():
    """The kernel's solves are its own loops (no ``np.linalg`` in compiled code, which would make numba
    import scipy.linalg.cython_lapack when the code runs): stepping, projecting and sampling a top on a
    ball joint in the kernel, compiled or loaded from numba's cache, imports no scipy.linalg, so that a
    run the kernel covers needs no LAPACK (its initial projection is the kernel's too). The system
    is built without the contact modules: packing registers every piece itself (the kernel's types
    do not depend on the caller's imports)."""
    pytest.importorskip("numba")
    code = """
import numpy as np
from viz3d.bodies import Bodies
from viz3d.constraints import build_layout
from viz3d.coordinates import EulerSwitching
from viz3d.forces import Gravity
from viz3d.formulation import Projection
from viz3d.integrators.tableaus import RK4
from viz3d.joints import BallJoint
from viz3d.kernel import KernelStepper, kernel_for
from viz3d.system import State, System

bodies = Bodies(("top",), np.array([1.0]), np.diag([0.02, 0.02, 0.01])[None])
joint = BallJoint(("pivot",), np.array([[0, 1]]), np.array([[[0.0, 0.0, -0.1], [0.0, 0.0, 0.0]]]))
system = System(bodies, build_layout((joint,), bodies), (Gravity(bodies.mass, np.array([0.0, 0.0, -9.81]), (), 0),),
                EulerSwitching())
theta, chart = system.rotation.from_matrix(np.eye(3)[None])
q = system.join_q(np.array([[0.0, 0.0, 0.1]]), theta)
state = State(0.0, q, np.array([0.0, 0.0, 0.0, 0.0, 0.0, 50.0]), chart)
stepper = KernelStepper(kernel_for(system, Projection(1e-12)), RK4)
y, chart = state.y.copy(), state.chart.copy()
Y, charts, done, _, status, _ = stepper.frames(3, 2, 0, 0.0, 1e-3, y, chart, np.zeros(1, np.int64), 1e6)
assert done == 3 and status == 0, (done, status)
stepper.sample(np.array([0.002, 0.004, 0.006]), Y, charts, ())
"""
    modules = loaded_after(code)
    assert "viz3d.kernel.stepping" in modules
    assert not offending(modules, ("scipy.linalg", "scipy.linalg.cython_lapack", "scipy.sparse")), "the kernel needs LAPACK"


def test_the_command_starts_blas_on_one_thread_unless_the_user_chose_a_count():
    """``viz3d.__main__`` (the ``viz3d`` command) chooses OpenBLAS's thread count before numpy is
    imported (numpy starts the pool as it is imported): one thread, unless one of the variables
    OpenBLAS reads is set. Library users and ``cli.main`` keep their own."""
    from viz3d.process import BLAS_THREADS, single_threaded_blas

    env = {}
    single_threaded_blas(env)
    assert env == {"OPENBLAS_NUM_THREADS": "1"}
    for name in BLAS_THREADS:
        env = {name: "3"}
        single_threaded_blas(env)
        assert env == {name: "3"}
    probe = ("import os, sys\n"
             "seen = []\n"
             "class Probe:\n"
             "    def find_spec(self, name, path=None, target=None):\n"
             "        if name == 'numpy' and not seen:\n"
             "            seen.append(os.environ.get('OPENBLAS_NUM_THREADS'))\n"
             "sys.meta_path.insert(0, Probe())\n"
             "import viz3d.__main__\n"
             "print(seen)\n")
    clean = {k: v for k, v in __import__("os").environ.items() if k not in BLAS_THREADS}
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, env=clean, capture_output=True, text=True,
                         timeout=600, check=True)
    assert out.stdout.split() == ["['1']"]



def test_the_command_holds_the_collector_through_its_start_up_only():
    """``viz3d.__main__`` turns the cyclic garbage collector off for the start-up
    (``viz3d.process.hold_collector``: its full collections scanned numba's 10^5 objects again and
    again) and on again, the objects made so far frozen, at most ``STARTUP_SECONDS`` later; a process
    forked meanwhile collects from its start."""
    probe = ("import gc, os, time\n"
             "import viz3d.__main__\n"
             "from viz3d.process import STARTUP_SECONDS, hold_collector, release_collector\n"
             "held = not gc.isenabled()\n"
             "pid = os.fork()\n"
             "if pid == 0:\n"
             "    os._exit(0 if gc.isenabled() else 3)\n"
             "assert os.waitpid(pid, 0)[1] == 0, 'the forked child does not collect'\n"
             "time.sleep(STARTUP_SECONDS + 1.0)\n"
             "print(held, gc.isenabled(), gc.get_freeze_count() > 0)\n"
             "gc.unfreeze()\n"
             "hold_collector(60.0)\n"
             "again = not gc.isenabled()\n"
             "release_collector()\n"
             "print(again, gc.isenabled(), gc.get_freeze_count() > 0)\n")
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=600, check=True)
    assert out.stdout.split() == ["True", "True", "True"] * 2
