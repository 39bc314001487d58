"""BRDF lobes, their coefficients and spec parsing."""
