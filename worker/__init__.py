"""Task functions run on Dask workers: plain functions that call the numerical core (no FastAPI imports).

``worker.tasks`` holds the entry points the server submits; ``worker.blobs`` is the content-addressed store
both sides share (a directory on a common volume); ``worker.progress`` publishes stage and fraction as Dask
events.
"""
