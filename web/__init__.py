"""The browser viewer's files as the package data of ``relight.web`` (no Python code here).

pyproject.toml installs this folder as ``relight.web`` with index.html, src/, shaders/ and the three.js files the
viewer imports from node_modules/three (after ``npm ci --prefix web``) as package data; ``relight.resources``
finds them and ``relight.server.viewer`` serves them.
"""
