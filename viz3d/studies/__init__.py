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
