"""The relight HTTP service (FastAPI): uploads, BRDFs, plans, jobs on Dask, content-addressed results."""
