"""One machinery for every study (``viz3d sweep``, ``bench``, ``stability``, ``stowage``): a study is a
list of points (scene overrides), a measure (what one run computes: a row of plain data) and a
place to run them (this process, a local Dask cluster, or an existing Dask scheduler).

* ``viz3d.studies.plan``: the points of a grid (``--grid``) or a random sample (``--sample``);
* ``viz3d.studies.resolved``: scenes that travel resolved (tables and file bytes, no shared disk);
* ``viz3d.studies.execute``: the runs, their rows, the results store under ``--out``, progress.

docs/sweep.md describes the command and the fault handling.
"""

#: Seconds a study on an existing scheduler waits while no worker is attached (``--worker-timeout``);
#: here, not in ``execute``, so the command line's parser reads it without importing the machinery.
WORKER_TIMEOUT = 60.0

#: Keys a stowage ensemble may perturb (``viz3d stowage --perturb``; ``viz3d.studies.ensemble``): kind
#: and unit. The uncertain parameters of the haul (``viz3d.scene.ship.SHIP`` says what each is),
#: relative; the starting pose, ``ship.payout`` [m] (chain and anchor moved along the chain's path),
#: absolute. Here, like ``WORKER_TIMEOUT``, so the parser's help lists them without the machinery.
STOWAGE_PERTURBATIONS = {**{f"ship.{k}": ("relative", "") for k in (
    "mu", "mu_static", "stick_stiffness", "stick_damping", "restitution", "hauling_speed", "ramp_time",
    "stop_stiffness", "stop_damping")}, "ship.payout": ("absolute", "m")}
