"""BRDFs: validated specs (every model of ``relight.brdf``) and measured MERL files, content-addressed.

A BRDF's id is the SHA-256 of its canonical spec (``relight.brdf.spec.brdf_to_spec`` of the parsed lobe), so
``{"kind": "phong", "s": 32}``, ``"phong:s=32"`` and the same spec with its defaults spelled out share one id.
"""

from __future__ import annotations

import re
import struct
from collections.abc import AsyncIterator
from typing import Any

from pydantic import BaseModel, TypeAdapter, ValidationError

from relight.contract.brdfs import MAX_SUM_LOBES, BrdfSpec
from relight.contract.models import BrdfPublic
from relight.errors import InputError
from relight.server.config import Settings
from relight.server.db import Brdf, Database
from relight.server.problems import NotFound, Unprocessable
from relight.server.services import uploads
from relight.server.services.base import content_id, in_thread, utc
from relight.worker.blobs import DIGEST_RE, BlobStore
from relight.worker.specs import check_client_string

#: A MERL file starts with its three int32 dimensions (relight.brdf.measured).
MERL_HEADER_BYTES = 12
_SPEC_ADAPTER: TypeAdapter[Any] = TypeAdapter(BrdfSpec)


#: Longest spec string (eight terms with every parameter spelled out fit in a few hundred characters).
MAX_SPEC_CHARS = 2048
_TERM_START = re.compile(r"\s*[A-Za-z]")  # a term starts with its kind; "1e+5" splits into "...1e" and "5"


def _string_bounds(spec: str) -> None:
    """Length and term count of a spec string, checked before the core parses it (the object form's limits)."""
    if len(spec) > MAX_SPEC_CHARS:
        raise InputError(f"the spec string has {len(spec)} characters; at most {MAX_SPEC_CHARS} are accepted")
    terms = sum(1 for piece in spec.split("+") if _TERM_START.match(piece))
    if terms > MAX_SUM_LOBES:
        raise InputError(f"the spec string is a sum of {terms} terms; at most {MAX_SUM_LOBES} are accepted "
                         "(as for the object form's lobes)")


def _service_limits(canon: dict[str, Any]) -> None:
    """The canonical spec against the API's union (``relight.contract.brdfs``): the service limits hold whatever
    form the request used (string, object), with the offending field named."""
    try:
        _SPEC_ADAPTER.validate_python(canon)
    except ValidationError as exc:
        err = exc.errors()[0]
        where = ".".join(str(p) for p in err.get("loc", ()) if not str(p).endswith("Spec"))
        value = err.get("input")
        raise InputError(f"{where or 'spec'}: {err.get('msg', 'invalid')} (got {value!r:.80})") from None


def canonical_spec(spec: dict[str, Any] | str) -> tuple[dict[str, Any], Any]:
    """Parse with the core (its validation is the authority) and return the canonical spec and the lobe.

    Strings that would make the core open a file are refused first (``relight.worker.specs``), and so are strings
    longer or with more terms than the object form allows; the canonical spec then meets the API's limits."""
    from relight.brdf.spec import brdf_to_spec, parse_brdf

    try:
        if isinstance(spec, str):
            _string_bounds(spec)
            check_client_string(spec)
        lobe = parse_brdf(spec)
        canon = brdf_to_spec(lobe)
        if not isinstance(canon, dict):
            raise InputError(f"the core returned a non-object spec for {spec!r:.80}")
        if isinstance(spec, str):  # objects met the union already (strings never name lobe1d tables)
            _service_limits(canon)
    except (InputError, ValueError, TypeError) as exc:
        raise Unprocessable(f"brdf: {exc}") from None
    return canon, lobe


class BrdfService:
    def __init__(self, settings: Settings, db: Database, store: BlobStore) -> None:
        self.settings = settings
        self.db = db
        self.store = store
        self._cache: dict[str, BrdfPublic] = {}

    def _public(self, row: Brdf, lobe: Any | None = None) -> BrdfPublic:
        if lobe is None and row.measured_sha256 is None:
            _, lobe = canonical_spec(row.spec)
        measured = row.measured_sha256 is not None
        return BrdfPublic(
            id=row.id, kind=row.kind, spec=row.spec, radially_symmetric=bool(getattr(lobe, "radially_symmetric",
                                                                                        False)),
            center="R" if measured else getattr(lobe, "center", None), measured=measured,
            created_at=utc(row.created_at), links={"self": f"/brdfs/{row.id}"},
        )

    async def register(self, spec: dict[str, Any] | str, measured_sha256: str | None = None) -> tuple[BrdfPublic, bool]:
        """Store a BRDF under the hash of its canonical spec. Measured files are kept as they are (the spec names
        the file's digest); whether the core can prefilter them is checked when a job is planned."""
        if measured_sha256 is not None and isinstance(spec, dict):
            canon, lobe = spec, None
        else:
            canon, lobe = await in_thread(canonical_spec, spec)
        brdf_id = content_id(canon)
        cached = self._cache.get(brdf_id)
        if cached is not None:
            return cached, False
        row = Brdf(id=brdf_id, kind=str(canon.get("kind", type(lobe).__name__)), spec=canon,
                   measured_sha256=measured_sha256)

        def upsert() -> tuple[Brdf, bool]:
            from sqlalchemy.exc import IntegrityError

            try:
                with self.db.session() as s:
                    found = s.get(Brdf, brdf_id)
                    if found is not None:
                        return found, False
                    s.add(row)
                return row, True
            except IntegrityError:  # a concurrent request stored the same BRDF first
                with self.db.session() as s:
                    again = s.get(Brdf, brdf_id)
                if again is None:
                    raise
                return again, False

        stored, created = await in_thread(upsert)
        pub = self._public(stored, lobe)
        self._cache[brdf_id] = pub
        return pub, created

    async def create(self, spec: BaseModel) -> tuple[BrdfPublic, bool]:
        return await self.register(spec.model_dump(mode="json", exclude_none=True))

    async def get(self, brdf_id: str) -> BrdfPublic:
        cached = self._cache.get(brdf_id)
        if cached is not None:
            return cached

        def q() -> Brdf | None:
            with self.db.session() as s:
                return s.get(Brdf, brdf_id)

        row = await in_thread(q)
        if row is None:
            raise NotFound(f"no BRDF with id {brdf_id!r}")
        pub = await in_thread(self._public, row)
        self._cache[brdf_id] = pub
        return pub

    async def resolve(self, ref: str | BaseModel) -> BrdfPublic:
        """A BRDF id (must exist), a spec string such as ``phong:s=32``, or a spec object."""
        if isinstance(ref, BaseModel):
            return (await self.create(ref))[0]
        if DIGEST_RE.match(ref):
            return await self.get(ref)
        return (await self.register(ref))[0]

    async def upload_measured(self, chunks: AsyncIterator[bytes], content_length: str | None) -> tuple[BrdfPublic,
                                                                                                       bool]:
        """A MERL ``.binary`` file (``relight.brdf.measured``: dimensions (90, 90, 180), then float64 samples),
        checked by size and header while streaming and then read by the core."""
        from relight.brdf.measured import MERL_DIMS, MERL_FILE_BYTES, read_merl

        def check_head(head: bytes) -> None:
            if len(head) < MERL_HEADER_BYTES:
                raise Unprocessable(f"a MERL file starts with three int32 dimensions; the body has {len(head)} "
                                    "bytes")
            dims = struct.unpack("<3i", head[:MERL_HEADER_BYTES])
            if dims != tuple(MERL_DIMS):
                raise Unprocessable(f"MERL dimensions must be {tuple(MERL_DIMS)}, the file says {dims}")

        cap = min(MERL_FILE_BYTES, self.settings.max_upload_bytes)
        async with uploads.receive(self.store, chunks, content_length, cap=cap, what="the MERL .binary file",
                                   head_bytes=MERL_HEADER_BYTES, check_head=check_head,
                                   limit=f"{cap} bytes (a MERL file is exactly {MERL_FILE_BYTES} bytes; this server "
                                         f"accepts at most {self.settings.max_upload_bytes})") as up:
            if up.size != MERL_FILE_BYTES:
                raise Unprocessable(f"a MERL file is exactly {MERL_FILE_BYTES} bytes, the body has {up.size}")
            try:
                await in_thread(read_merl, up.writer.tmp_path)  # the core's own checks (finite values ...)
            except InputError as exc:
                raise Unprocessable(str(exc).replace(up.writer.tmp_path.name, "the upload")) from None
            await in_thread(self.store._install, up.writer.tmp_path, up.digest)
            digest = up.digest
        return await self.register({"kind": "merl", "sha256": digest}, measured_sha256=digest)
