"""``/tradeoffs``: accuracy against time for one map and BRDF, as a job (``relight.tradeoff``)."""

from __future__ import annotations

from collections.abc import AsyncIterator
from typing import Annotated

from fastapi import APIRouter, Response
from fastapi.sse import EventSourceResponse, ServerSentEvent

from relight.contract.models import TradeoffCreate, TradeoffPublic
from relight.server.api.deps import JobsDep, TradeoffsDep
from relight.server.api.routes.jobs import EVENTS_RESPONSES, existing, job_stream
from relight.server.problems import problem_responses
from relight.server.services.tradeoffs import TRADEOFF

router = APIRouter(prefix="/tradeoffs", tags=["tradeoffs"])


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


@router.get("/{tradeoff_id}/events", response_class=EventSourceResponse, responses=EVENTS_RESPONSES)
async def tradeoff_events(tradeoff_id: Annotated[str, existing(TRADEOFF.name, "tradeoff_id")],
                          jobs: JobsDep) -> AsyncIterator[ServerSentEvent]:
    """The sweep's job as server-sent events until it ends (``/jobs/{id}/events``)."""
    async for event in job_stream(jobs, tradeoff_id):
        yield event


@router.delete("/{tradeoff_id}", response_model=TradeoffPublic, responses=problem_responses(401, 404, 409, 422))
async def cancel_tradeoff(tradeoff_id: str, jobs: JobsDep, tradeoffs: TradeoffsDep) -> TradeoffPublic:
    """Cancel a queued or running sweep (409 if it already finished)."""
    await jobs.cancel(tradeoff_id, TRADEOFF.name)
    return await tradeoffs.get(tradeoff_id)
