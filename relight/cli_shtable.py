"""SH-table command of the ``relight`` CLI (seed 003 §3; ``relight.sh_table``).

    relight sh-table BRDF_SPEC [--order F] [--resolution R] [--layout parabolic|hemi-octahedral] --out TABLE.npz|.exr

``BRDF_SPEC`` is any spec of ``relight.brdf.spec.parse_frame_brdf`` (isotropic, anisotropic, measured). The
``.npz`` holds ``coefficients`` (R x R x (F+1)^2 x C float32, relight's real basis in the local frame x = tangent,
y = bitangent, z = normal), ``views`` (R x R x 3, the unit local view of each texel), ``valid`` (R x R) and
``manifest`` (JSON); the ``.exr`` holds one float16 RGB layer per coefficient (docs/conventions.md, "SH tables").
Prints one JSON line (the manifest). Errors raise ``InputError`` (exit status 2, one line).
"""

from __future__ import annotations

import argparse
import json
from typing import Any


def cmd_sh_table(args: argparse.Namespace) -> int:
    from relight.brdf.spec import parse_frame_brdf
    from relight.sh_table import build_table, write_table

    brdf = parse_frame_brdf(args.brdf)
    table = build_table(brdf, order=args.order, resolution=args.resolution, layout=args.layout)
    man = write_table(args.out, table)
    print(json.dumps({"out": str(args.out), **man}, sort_keys=True))
    return 0


#: ``relight.sh_table``'s defaults, repeated so that registering the command imports nothing numerical
#: (tests/relight/test_cli_shtable.py checks that they agree).
DEFAULT_ORDER, DEFAULT_RESOLUTION, DEFAULT_LAYOUT = 4, 128, "parabolic"


def register(subparsers: Any) -> None:
    """Add ``sh-table`` to the ``relight`` command line."""
    st = subparsers.add_parser("sh-table", help="per-view SH table of a BRDF's product function (seed 003)")
    st.add_argument("brdf", help="BRDF spec, e.g. 'ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0'")
    st.add_argument("--order", type=int, default=DEFAULT_ORDER, help="SH order F: l <= F, (F+1)^2 coefficients")
    st.add_argument("--resolution", type=int, default=DEFAULT_RESOLUTION, help="view map size R (R x R)")
    st.add_argument("--layout", default=DEFAULT_LAYOUT, choices=["parabolic", "hemi-octahedral"])
    st.add_argument("--out", required=True, help="TABLE.npz or TABLE.exr")
    st.set_defaults(func=cmd_sh_table)
