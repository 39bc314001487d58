"""Dependencies as ``Annotated`` aliases: routes declare what they need.

Every dependency is ``async``: FastAPI runs plain ``def`` dependencies in the thread pool, a thread hop per
dependency per request, which on the cached-download path costs more than the work itself. Settings come from
the app (``create_app(settings)``, default :func:`relight.server.config.get_settings`); a test passes its own.
"""

from __future__ import annotations

import hashlib
import hmac
from collections.abc import Mapping
from typing import Annotated

from fastapi import Depends, Request

from relight.server.config import Settings
from relight.server.problems import Unauthorized
from relight.server.services.brdfs import BrdfService
from relight.server.services.envmaps import EnvmapService
from relight.server.services.jobs import JobService
from relight.server.services.meshes import MeshService
from relight.server.services.plans import PlanService
from relight.server.services.render import RenderService
from relight.server.services.scenes import SceneService
from relight.server.services.shrms import ShrmService
from relight.server.services.tradeoffs import TradeoffService
from relight.server.services.visibility import VisibilityService
from relight.server.state import Services


async def get_app_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


SettingsDep = Annotated[Settings, Depends(get_app_settings)]


def _services(request: Request) -> Services:
    services: Services = request.app.state.services
    return services


async def get_services(request: Request) -> Services:
    return _services(request)


ServicesDep = Annotated[Services, Depends(get_services)]


# Each takes the request directly (not ServicesDep): one dependency level less on every request.
async def get_envmaps(request: Request) -> EnvmapService:
    return _services(request).envmaps


async def get_meshes(request: Request) -> MeshService:
    return _services(request).meshes


async def get_brdfs(request: Request) -> BrdfService:
    return _services(request).brdfs


async def get_plans(request: Request) -> PlanService:
    return _services(request).plans


async def get_jobs(request: Request) -> JobService:
    return _services(request).jobs


async def get_shrms(request: Request) -> ShrmService:
    return _services(request).shrms


async def get_tradeoffs(request: Request) -> TradeoffService:
    return _services(request).tradeoffs


async def get_scenes(request: Request) -> SceneService:
    return _services(request).scenes


async def get_visibility(request: Request) -> VisibilityService:
    return _services(request).visibility


async def get_render(request: Request) -> RenderService:
    return _services(request).render


EnvmapsDep = Annotated[EnvmapService, Depends(get_envmaps)]
MeshesDep = Annotated[MeshService, Depends(get_meshes)]
BrdfsDep = Annotated[BrdfService, Depends(get_brdfs)]
PlansDep = Annotated[PlanService, Depends(get_plans)]
JobsDep = Annotated[JobService, Depends(get_jobs)]
ShrmsDep = Annotated[ShrmService, Depends(get_shrms)]
TradeoffsDep = Annotated[TradeoffService, Depends(get_tradeoffs)]
ScenesDep = Annotated[SceneService, Depends(get_scenes)]
RenderDep = Annotated[RenderService, Depends(get_render)]
VisibilityDep = Annotated[VisibilityService, Depends(get_visibility)]


def presented_key(headers: Mapping[str, str]) -> str | None:
    auth = headers.get("authorization")
    if auth and auth[:7].lower() == "bearer ":
        return auth[7:].strip()
    return headers.get("x-api-key")


def key_problem(settings: Settings, headers: Mapping[str, str]) -> Unauthorized | None:
    """None when the request may pass: no key hashes are configured, or the SHA-256 of the presented key matches
    one (constant-time comparison against every configured hash). Else the 401 to answer."""
    if not settings.api_key_hashes:
        return None
    key = presented_key(headers)
    if not key:
        return Unauthorized("this server needs an API key: send 'Authorization: Bearer <key>' or 'X-API-Key'",
                            headers={"WWW-Authenticate": "Bearer"})
    digest = hashlib.sha256(key.encode()).hexdigest()
    ok = False
    for h in settings.api_key_hashes:
        ok |= hmac.compare_digest(digest, h)
    if not ok:
        return Unauthorized("the API key is not valid", headers={"WWW-Authenticate": 'Bearer error="invalid_token"'})
    return None


async def require_api_key(request: Request) -> None:
    """Raise :func:`key_problem`'s 401, if any (request bodies were checked already by
    :class:`relight.server.limits.BodyLimit`, before they were read)."""
    problem = key_problem(request.app.state.settings, request.headers)
    if problem is not None:
        raise problem


ApiKey = Depends(require_api_key)
