"""One machinery for every study (``viz3d sweep``, ``bench``, ``stability``, ``stowage``): a study is a
list of points (scene overrides), a measure (what one run computes: a row of plain data) and a
place to run them (this process, a local Dask cluster, or an existing Dask scheduler).

* ``viz3d.studies.plan``: the points of a grid (``--grid``) or a random sample (``--sample``);
* ``viz3d.studies.resolved``: scenes that travel resolved (tables and file bytes, no shared disk);
* ``viz3d.studies.execute``: the runs, their rows, the results store under ``--out``, progress.

docs/sweep.md describes the command and the fault handling.
"""
