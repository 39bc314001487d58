"""``/tradeoffs``: accuracy against time for one map and BRDF, as a job (``relight.tradeoff``)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Response

from relight.contract.models import TradeoffCreate, TradeoffPublic
from relight.server.problems import problem_responses
from relight.server.services.tradeoffs import TradeoffService, tradeoff_service

router = APIRouter(prefix="/tradeoffs", tags=["tradeoffs"])

TradeoffsDep = Annotated[TradeoffService, Depends(tradeoff_service)]


@router.post("", status_code=202, response_model=TradeoffPublic,
             responses={200: {"description": "the sweep exists already (finished)", "model": TradeoffPublic},
                        **problem_responses(400, 401, 404, 422, 429, 503)})
async def submit(body: TradeoffCreate, response: Response, tradeoffs: TradeoffsDep) -> TradeoffPublic:
    """Start (or join) the sweep: 202 with its id, or 200 with the points when it has finished already."""
    pub, status = await tradeoffs.submit(body)
    response.status_code = status
    response.headers["Location"] = f"/tradeoffs/{pub.id}"
    return pub


@router.get("/{tradeoff_id}", response_model=TradeoffPublic, responses=problem_responses(401, 404, 422))
async def get_tradeoff(tradeoff_id: str, tradeoffs: TradeoffsDep) -> TradeoffPublic:
    """State; once succeeded, the points (``tradeoff.json``) and what they were measured on (``meta``)."""
    return await tradeoffs.get(tradeoff_id)
