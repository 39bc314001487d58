"""Task functions run on Dask workers: plain functions that call the numerical core (no FastAPI imports).

``relight.worker.tasks`` holds the entry points the server submits; ``relight.worker.blobs`` is the content-addressed
store
both sides share (a directory on a common volume); ``relight.worker.progress`` publishes stage and fraction as Dask
events.
"""
