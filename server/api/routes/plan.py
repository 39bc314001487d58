"""``/plan``: orders, predicted error and time, and the representation, without computing anything."""

from __future__ import annotations

from fastapi import APIRouter, Request

from relight.contract.models import PlanCreate, PlanPublic
from relight.server.api.deps import PlansDep
from relight.server.api.http import until_disconnect
from relight.server.problems import problem_responses

router = APIRouter(tags=["plan"])


@router.post("/plan", response_model=PlanPublic, responses=problem_responses(400, 401, 404, 422))
async def plan(body: PlanCreate, request: Request, plans: PlansDep) -> PlanPublic:
    """Predict what ``POST /shrms`` with the same body would do (cheap: spectra only)."""
    return await until_disconnect(request, plans.plan(body))  # a client gone stops the planning sandbox
