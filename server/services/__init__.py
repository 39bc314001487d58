"""Service layer: the logic behind the routes (routes only translate HTTP to these calls)."""
