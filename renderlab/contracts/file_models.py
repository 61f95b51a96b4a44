"""One validated model per metadata file the lab reads (read with :func:`renderlab.inputs.read_model`).

==========================  ==========================================  ==========================================
model                       file                                        read by
==========================  ==========================================  ==========================================
:class:`CampaignManifest`   ``campaign.json`` (campaign, published)     ``report``, ``publish``, ``info``, resume
:class:`RunStatus`          ``runs/NNNNNN/status.json`` of a campaign   the same
:data:`RunStatuses`         ``runs.json`` of a published study          the same
:class:`TruthManifest`      ``manifest.json`` of a truth set            ``measure``, ``export``, ``info``, studies
==========================  ==========================================  ==========================================

(The a-priori file of ``measure --images`` has its own model, :class:`renderlab.measurement.apriori.AprioriFile`.)
The models are strict: no string is read as a number (``"64"`` for a width), no float as an integer, no boolean
as either; numbers are finite and inside physical ranges (:data:`FOCAL_MAX_PX` …); lists and strings have
bounded lengths; epochs lie in :data:`renderlab.inputs.EPOCH_YEARS`. Keys a writer of the file never wrote are
refused where the lab writes the whole file (``campaign.json``, ``status.json``, ``runs.json``); records that worlds
and studies extend (a truth set's frame records) keep their other keys, unchecked here, for their own readers.
"""

from __future__ import annotations

import hashlib
import json
import math
from typing import Annotated, Any, Literal, Union

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    StringConstraints,
    TypeAdapter,
    field_validator,
    model_validator,
)

from renderlab.inputs import COEFF_MAX, EPOCH_YEARS, PIXEL_MAX, check_epoch_text  # noqa: F401  (re-exported)

#: the most runs a campaign plan may have
MAX_RUNS = 1_000_000
#: the most frames a truth set may list
MAX_FRAMES = 1_000_000
#: image sides, px
MAX_SIDE_PX = 65_535
#: largest focal length, |principal point|, |skew| in pixels; largest |distortion coefficient| (renderlab.inputs)
FOCAL_MAX_PX = PIXEL_MAX
#: largest |position|, m (100 au)
POSITION_MAX_M = 1.5e13
#: largest |time| in s from a truth set's start (about 3000 years)
TIME_MAX_S = 1e11

Finite = Annotated[float, Field(allow_inf_nan=False)]
Coeff = Annotated[float, Field(ge=-COEFF_MAX, le=COEFF_MAX, allow_inf_nan=False)]
NonNeg = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Side = Annotated[int, Field(ge=1, le=MAX_SIDE_PX)]
Focal = Annotated[float, Field(gt=0, le=FOCAL_MAX_PX, allow_inf_nan=False)]
Pixel = Annotated[float, Field(ge=-PIXEL_MAX, le=PIXEL_MAX, allow_inf_nan=False)]
Position = Annotated[float, Field(ge=-POSITION_MAX_M, le=POSITION_MAX_M, allow_inf_nan=False)]
Vec3 = Annotated[list[Position], Field(min_length=3, max_length=3)]
Quat = Annotated[list[Annotated[float, Field(ge=-2, le=2, allow_inf_nan=False)]], Field(min_length=4, max_length=4)]
Name = Annotated[str, StringConstraints(min_length=1, max_length=200)]
Text = Annotated[str, StringConstraints(max_length=100_000)]
Identifier = Annotated[str, AfterValidator(lambda v: _identifier(v))]
RelPath = Annotated[str, StringConstraints(min_length=1, max_length=1024, pattern=r"^[^\x00]*$")]
RunIndex = Annotated[int, Field(ge=0, lt=MAX_RUNS)]

def _identifier(v: str) -> str:
    if not (v.isidentifier() and v.isascii() and len(v) <= 64):
        raise ValueError("must be plain table names (identifiers), never paths")
    return v




class FileModel(BaseModel):
    """Strict: no coercion (``"64"`` is not 64, ``1.0`` not an int, ``true`` not 1), finite numbers, no unknown
    keys."""

    model_config = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False)


class OpenRecord(FileModel):
    """A record other readers extend: unknown keys are kept (and left to them)."""

    model_config = ConfigDict(strict=True, extra="allow", allow_inf_nan=False)


Epoch = Annotated[str, StringConstraints(max_length=64)]


def _unit_norm(q: list[float], what: str) -> list[float]:
    n = math.sqrt(sum(v * v for v in q))
    if not n > 1e-6:
        raise ValueError(f"{what} has zero norm")
    return q


# ----------------------------------------------------------------------------------------- campaign.json
class SeedInfo(FileModel):
    entropy: Annotated[int, Field(ge=0, lt=2 ** 128)]
    run_seed: Annotated[str, StringConstraints(max_length=200)]


PertValue = Union[Finite, list[Finite], list[list[Finite]], dict[str, Finite], None]


class PlanScenario(OpenRecord):
    """The scenario of a plan, as far as reports read it (the runs validate it in full)."""

    name: Name | None = None
    description: Annotated[str, StringConstraints(max_length=10_000)] | None = None
    perturbations: dict[str, PertValue] | None = None
    world: dict[str, Any] | None = None
    trajectory: dict[str, Any] | None = None


class Plan(FileModel):
    study: Name
    runs: Annotated[int, Field(ge=1, le=MAX_RUNS)]
    seed: SeedInfo
    scenario: PlanScenario
    files: dict[str, Annotated[str, StringConstraints(max_length=100)]] | None = None


class CampaignManifest(FileModel):
    format: Literal["renderlab.campaign/1"]
    name: Name
    plan: Plan
    plan_digest: Annotated[str, StringConstraints(max_length=64)] | None = None
    scenario_dir: RelPath | None = None
    versions: dict[str, Annotated[str, StringConstraints(max_length=200)]] = {}


# ----------------------------------------------------------------------------------------- status.json, runs.json
class RunStatus(FileModel):
    run: RunIndex
    status: Literal["ok", "error"]
    error: Text = ""
    seconds: NonNeg | None = None
    tables: Annotated[list[Identifier], Field(max_length=1000)] = []
    traceback: Text | None = None
    env_errno: Annotated[str, StringConstraints(max_length=16)] | None = None

    @model_validator(mode="after")
    def _unique_tables(self):
        if len(set(self.tables)) != len(self.tables):
            raise ValueError("'tables' names a table twice")
        return self


#: ``runs.json`` as written before it named its campaign: the bare list of the runs' statuses
RunStatuses = TypeAdapter(Annotated[list[RunStatus], Field(max_length=MAX_RUNS)], config=ConfigDict(strict=True))
RUNS_FORMAT = "renderlab.runs/1"


class RunStatusFile(FileModel):
    """``runs.json``: the runs' statuses and the digest of the plan they ran (:func:`plan_digest` of
    ``campaign.json``'s plan), so that two campaigns whose runs all ended alike still write different files."""

    format: Literal["renderlab.runs/1"]
    plan_digest: Annotated[str, StringConstraints(max_length=64)]
    runs: Annotated[list[RunStatus], Field(max_length=MAX_RUNS)]


def plan_digest(plan: dict) -> str:
    """The 16-hex digest of a campaign plan (``campaign.json``'s ``plan``): SHA-256 of its sorted, compact JSON."""
    text = json.dumps(plan, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# ----------------------------------------------------------------------------------------- manifest.json
class CameraRecord(FileModel):
    """A camera as truth sets and a-priori files write it (:class:`renderlab.geometry.camera.CameraModel`)."""

    width: Side
    height: Side
    fx: Focal
    fy: Focal
    cx: Pixel
    cy: Pixel
    skew: Pixel = 0.0
    skew_yx: Pixel = 0.0
    model: Literal["pinhole", "brown", "owen", "opencv", "kannala_brandt"] = "pinhole"
    distortion: Annotated[dict[Annotated[str, StringConstraints(max_length=16)], Coeff], Field(max_length=32)] = {}


class PoseRecord(OpenRecord):
    position_m: Vec3
    quat_render_from_cam_xyzw: Quat

    @field_validator("quat_render_from_cam_xyzw")
    @classmethod
    def _q(cls, q):
        return _unit_norm(q, "the quaternion")


class FrameRecord(OpenRecord):
    index: Annotated[int, Field(ge=0, lt=MAX_FRAMES * 100)]
    time_s: Annotated[float, Field(ge=-TIME_MAX_S, le=TIME_MAX_S, allow_inf_nan=False)]
    exr: RelPath
    dn: RelPath
    dn_preview: RelPath | None = None
    camera: CameraRecord | None = None
    pose: PoseRecord | None = None
    epoch_utc: Epoch | None = None

    @field_validator("epoch_utc")
    @classmethod
    def _epoch(cls, v):
        return v if v is None else check_epoch_text(v)


class TruthManifest(OpenRecord):
    format: Literal["renderlab.truthset/1"]
    frames: Annotated[list[FrameRecord], Field(max_length=MAX_FRAMES)]
    scenario: dict[str, Any] = {}
    seed: Annotated[int, Field(ge=0)] | None = None
    render_frame: dict[str, Any] | None = None
    renderer: dict[str, Any] | None = None
