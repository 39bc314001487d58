"""OpenGL side of relight: the GLSL loader shared with the browser viewer (``shaders``), the SHRM texture layout
read from a result's manifest (``layout``), a headless moderngl renderer (``render``, ``mesh``) and the plain
functions behind the viewer's image endpoints (``views``). Seed 000 §7.5 (eq. 12) and §4 (eq. 6)."""
