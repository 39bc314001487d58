"""The sample data as the package data of ``relight.data`` (no Python code here; README.md lists the files).

pyproject.toml installs this folder as ``relight.data`` with envmaps/*.exr and meshes/*.obj as package data;
``relight.resources`` finds them (the renderer's meshes, the server's sample maps and viewer meshes).
"""
