"""The simulator, navigation, situated-QA and map_summary tools return typed results: a
pydantic model per tool whose JSON is the text block a client reads, unchanged."""

from __future__ import annotations

import inspect
import json
import os
import typing

import pytest
from mcp import Client
from pydantic import BaseModel, ValidationError

from glmap_tools.app.catalog import TOOLS
from glmap_tools.app.results import ImageResult, MapInfo, Reply
from glmap_tools.app.sim_results import (
    FrontiersResult,
    LookAroundResult,
    NavigateResult,
    NavStepResult,
    SimResult,
    SimStatus,
    ValueMapResult,
    Waypoint,
)
from glmap_tools.app.tools_sqa import SituationResult
from glmap_tools.server import build_server
from tests.test_server_fixtures import config, frame_args

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
EPISODE = "tune/objectnav/s03-013"

TYPED = {
    "sim_reset": SimResult,
    "sim_step": SimResult,
    "look_around": LookAroundResult,
    "value_map": ValueMapResult,
    "frontiers": FrontiersResult,
    "navigate_to": NavigateResult,
    "nav_step": NavStepResult,
    "locate_situation": SituationResult,
    "map_summary": MapInfo,
}


def data_model(fn: typing.Callable[..., object]) -> type[BaseModel] | None:
    """The model of an ImageResult tool's data, from its return annotation."""
    returned = inspect.signature(fn).return_annotation
    assert isinstance(returned, type) and issubclass(returned, ImageResult)
    args = returned.__pydantic_generic_metadata__["args"]
    return args[0] if args else None


def test_every_tool_that_returns_json_with_images_declares_the_model_of_that_json():
    with_images = {t.name: data_model(t.fn) for t in TOOLS if _returns_images(t.fn)}
    assert with_images == {**TYPED, "render_view": None}  # render_view: notes and images only


def _returns_images(fn: typing.Callable[..., object]) -> bool:
    returned = inspect.signature(fn).return_annotation
    return isinstance(returned, type) and issubclass(returned, ImageResult)


def test_every_field_of_a_tool_result_that_is_not_plain_from_its_name_is_described():
    plain = {"goal", "units", "outcome", "reason", "walk_steps", "walk_collisions", "step"}
    plain |= {"action", "new_collisions", "id", "score", "in_sight", "would_succeed"}
    plain |= {"instances", "regions", "unit_distance_m", "situation", "around", "views"}
    for model in [m for m in TYPED.values() if issubclass(m, Reply)]:
        for name, field in model.model_fields.items():
            if name not in plain and not issubclass(_model_of(field.annotation), BaseModel):
                assert field.description, f"{model.__name__}.{name} is not described"


def _model_of(annotation: object) -> type:
    """The model inside `X | None` or `list[X]`, else object."""
    for arg in typing.get_args(annotation) or (annotation,):
        if isinstance(arg, type) and issubclass(arg, BaseModel):
            return arg
    return object


def test_an_optional_field_not_given_is_left_out_of_the_text_not_sent_as_null():
    plain = Waypoint(kind="none", score=0.0, reason="nothing left")
    aimed = Waypoint(kind="frontier", score=0.5, reason="r", xy=(1.0, 2.0), unit_id=None)
    text = '{"kind":"none","score":0.0,"reason":"nothing left"}'
    assert ImageResult(data=plain).texts() == [text]
    assert json.loads(ImageResult(data=aimed).texts()[0]) == {
        "kind": "frontier",
        "xy": [1.0, 2.0],
        "unit_id": None,  # given as null: sent as null
        "score": 0.5,
        "reason": "r",
    }


def test_a_tool_result_refuses_an_unknown_field_and_a_wrong_type():
    with pytest.raises(ValidationError, match="extra"):
        Waypoint(kind="goal", score=1.0, reason="r", unit=3)  # type: ignore[call-arg]
    aimed = Waypoint(kind="goal", score=1.0, reason="r")
    with pytest.raises(ValidationError):
        aimed.unit_id = "the sofa"  # type: ignore[assignment]


def test_the_episode_status_comes_after_a_tools_own_fields_as_the_text_has_it():
    status = list(SimStatus.model_fields)
    for model in (NavStepResult, NavigateResult):
        fields = list(model.model_fields)
        assert fields[-len(status) :] == status and fields[0] == "outcome"
    assert list(SimResult.model_fields)[: len(status)] == status


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


@pytest.mark.anyio
async def test_the_text_of_each_typed_tool_is_its_models_json_field_for_field(tmp_path):
    calls = [
        ("observe_frame", frame_args((0.0, -2.6, 1.4))),
        ("map_summary", {"include_image": False}),
        ("locate_situation", {"situation": "standing at the dining table facing the blue chair"}),
        ("sim_reset", {"episode": EPISODE}),
        ("sim_step", {"action": "turn_left", "repeat": 2}),
        ("look_around", {}),
        ("value_map", {"scores": {"1": 0.5}}),
        ("frontiers", {"top_k": 3}),
        ("nav_step", {"actions": 2, "details": True}),
        ("nav_step", {"actions": 2}),
        ("navigate_to", {"x": 15.43, "y": 3.93, "max_steps": 4}),
    ]
    async with Client(build_server(config(tmp_path, sim_size=(160, 120)))) as client:
        for name, args in calls:
            result = await client.call_tool(name, args)
            assert not result.is_error, (name, result.content[0].text)
            if name not in TYPED:
                continue
            text = result.content[0].text
            model = TYPED[name].model_validate_json(text)  # every key known, every type right
            again = model.given() if isinstance(model, Reply) else model.model_dump(mode="json")
            assert json.dumps(again, separators=(",", ":"), ensure_ascii=False) == text, name
            assert result.structured_content is None  # as before: JSON text and images
