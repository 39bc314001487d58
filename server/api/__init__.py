"""HTTP layer: routers (one per resource), dependencies and response helpers."""
