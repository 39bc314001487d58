"""Every request and response model of the API, re-exported from the modules that define them (one per group of
routes), so ``from relight.contract.models import X`` names any model:

- :mod:`relight.contract.base`: base models, ids, job states, problems, health
- :mod:`relight.contract.resources`: envmaps, meshes, BRDFs
- :mod:`relight.contract.reports`: the core reports' models
- :mod:`relight.contract.jobs`: SHRM requests, ``POST /jobs``, jobs, manifests
- :mod:`relight.contract.visibility`: mesh visibility
- :mod:`relight.contract.gaussian`: seed 002's Gaussian kinds
- :mod:`relight.contract.engine`: engine-ready exports (issue 17)
- :mod:`relight.contract.tradeoffs`: accuracy–time sweeps
- :mod:`relight.contract.scenes`: scenes for the planner
"""

from __future__ import annotations

from relight.contract.base import (
    ACTIVE_STATES,
    Digest,
    Fraction,
    Health,
    JobState,
    Problem,
    Public,
    Strict,
    Vector3,
    parse_view,
)
from relight.contract.engine import SUN_PATTERN, DfgCreate, IblCreate
from relight.contract.gaussian import (
    GaussianChainCreate,
    GaussianFitCreate,
)
from relight.contract.jobs import (
    JobCreate,
    JobKindList,
    JobList,
    JobParams,
    JobPublic,
    JobSubmit,
    LayerInfo,
    Measurement,
    OutputShape,
    PlanCreate,
    PlanPublic,
    Prediction,
    ShrmCreate,
    ShrmManifest,
    SunLobeOrders,
    SunPlan,
)
from relight.contract.reports import (
    CoreReport,
    Orders,
    PredictedError,
    ViewBand,
)
from relight.contract.resources import (
    BrdfPublic,
    BrdfRef,
    EnvmapList,
    EnvmapPublic,
    MeshList,
    MeshPublic,
)
from relight.contract.scenes import (
    MAX_PREVIEW_SIZE,
    SceneCreate,
    SceneName,
    SceneObjectCreate,
    ScenePublic,
    Shape,
    TangentField,
)
from relight.contract.tradeoffs import (
    TradeoffCreate,
    TradeoffPublic,
)
from relight.contract.visibility import (
    VisibilityCreate,
    VisibilityKind,
)

__all__ = [
    "ACTIVE_STATES",
    "BrdfPublic",
    "BrdfRef",
    "CoreReport",
    "DfgCreate",
    "Digest",
    "EnvmapList",
    "EnvmapPublic",
    "Fraction",
    "GaussianChainCreate",
    "GaussianFitCreate",
    "Health",
    "IblCreate",
    "JobCreate",
    "JobKindList",
    "JobList",
    "JobParams",
    "JobPublic",
    "JobState",
    "JobSubmit",
    "LayerInfo",
    "MAX_PREVIEW_SIZE",
    "Measurement",
    "MeshList",
    "MeshPublic",
    "Orders",
    "OutputShape",
    "PlanCreate",
    "PlanPublic",
    "PredictedError",
    "Prediction",
    "Problem",
    "Public",
    "SceneCreate",
    "SceneName",
    "SceneObjectCreate",
    "TangentField",
    "ScenePublic",
    "Shape",
    "ShrmCreate",
    "ShrmManifest",
    "SUN_PATTERN",
    "SunLobeOrders",
    "SunPlan",
    "Strict",
    "TradeoffCreate",
    "TradeoffPublic",
    "Vector3",
    "ViewBand",
    "VisibilityCreate",
    "VisibilityKind",
    "parse_view",
]
