"""Pictures as agents are sent them: lossless PNG colour and 16-bit depth, one name per
content, chat image parts the openai client accepts, and a Cameras section from which a
reader of the prompt alone turns a depth pixel into the world point it shows."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from openai.types.chat import ChatCompletionMessageParam
from pydantic import TypeAdapter
from scipy.spatial.transform import Rotation

from actionreasoning.agents.memory import TaskMemory
from actionreasoning.agents.observation import Observation
from actionreasoning.agents.prompt import cameras_text, render_prompt
from actionreasoning.agents.spec import agent_specs
from actionreasoning.agents.tiers import ToolTier
from actionreasoning.agents.view import StateView
from actionreasoning.reasoners.chat import image_urls, message_text, user_message
from actionreasoning.reasoners.reference_server import image_tokens, png_size
from actionreasoning.sim.eyes import capture
from actionreasoning.sim.perceive import Sensor
from actionreasoning.sim.scene import Scene
from actionreasoning.world.models import Progress, WorldState
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.pictures import (
    CAMERAS,
    DEPTH_UNIT_M,
    SHOWN_NAMES,
    Picture,
    PictureKind,
    colour_png,
    depth_png,
    read_colour,
    read_depth,
)
from actionreasoning.world.scenarios import NOISE
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.tolerances import Tolerances


def test_colour_round_trips_exactly_and_the_same_image_gives_the_same_bytes() -> None:
    rgb = np.random.default_rng(0).integers(0, 256, (48, 64, 3), dtype=np.uint8)
    png = colour_png(rgb)
    assert np.array_equal(read_colour(png), rgb)
    assert colour_png(rgb.copy()) == png
    with pytest.raises(ValueError, match="h x w x 3 uint8"):
        colour_png(rgb.astype(np.float32))


def test_depth_round_trips_to_half_a_count() -> None:
    depth = np.random.default_rng(1).uniform(0.05, 5.0, (40, 30)).astype(np.float32)
    back = read_depth(depth_png(depth))
    assert back.dtype == np.float32 and back.shape == depth.shape
    assert np.max(np.abs(back - depth)) <= DEPTH_UNIT_M / 2 + 1e-6


def test_depth_without_a_reading_is_zero_and_reads_back_as_nan() -> None:
    depth = np.array([[1.2345, np.nan], [np.inf, 7.0]], dtype=np.float32)  # 7 m: past 16 bits
    back = read_depth(depth_png(depth))
    assert back[0, 0] == pytest.approx(1.2345, abs=1e-6)
    assert np.isnan(back[0, 1]) and np.isnan(back[1, 0]) and np.isnan(back[1, 1])


def test_a_picture_is_named_by_camera_and_kind_and_hashed_by_content() -> None:
    png = colour_png(np.zeros((2, 2, 3), dtype=np.uint8))
    picture = Picture("top_down", PictureKind.COLOUR, png)
    assert picture.name == "top_down.colour"
    assert picture.sha256 == Picture("overview", PictureKind.COLOUR, png).sha256
    assert picture.data_url.startswith("data:image/png;base64,iVBORw0KGgo")


def test_image_parts_are_messages_the_openai_client_accepts() -> None:
    pictures = [Picture("top_down", kind, depth_png(np.ones((3, 5)))) for kind in PictureKind]
    message = user_message("prompt", pictures)
    TypeAdapter(ChatCompletionMessageParam).validate_python(message)
    assert message["content"][0] == {"type": "text", "text": "prompt"}
    assert image_urls(message) == [p.data_url for p in pictures]
    assert message_text(message) == "prompt"
    # Without pictures, the message is the plain text one it always was.
    assert user_message("prompt") == {"role": "user", "content": "prompt"}
    assert image_urls(user_message("prompt")) == []


def test_image_tokens_are_counted_as_openai_counts_high_detail_tiles() -> None:
    """85 + 170 per 512-pixel tile: 640 x 640 is 2 x 2 tiles, 480 x 360 one, 640 x 480
    2 x 1; 4096 x 1024 is scaled to 2048 x 512 and then kept (its short side under 768)."""

    def url(width: int, height: int) -> str:
        picture = Picture("c", PictureKind.DEPTH, depth_png(np.ones((height, width))))
        return picture.data_url

    assert png_size(url(640, 480)) == (640, 480)
    assert [image_tokens(url(*size)) for size in ((640, 640), (480, 360), (640, 480))] == [
        85 + 4 * 170,
        85 + 170,
        85 + 2 * 170,
    ]
    assert image_tokens(url(4096, 1024)) == 85 + 4 * 170
    assert png_size("data:image/jpeg;base64,/9j/") is None
    assert image_tokens("https://example.com/a.png") == 85 + 170


def prompt_cameras(prompt: str) -> list[dict[str, object]]:
    """The camera JSON of a prompt's Cameras section, as a model reads it."""
    section = prompt.partition("## Cameras\n")[2].partition("\n## ")[0]
    found = re.search(r"```json\n(.*?)\n```", section, re.S)
    assert found is not None
    cameras: list[dict[str, object]] = json.loads(found.group(1))
    return cameras


def test_a_prompt_reader_turns_a_depth_pixel_into_the_brick_it_shows(scene: Scene) -> None:
    """With ``both``, the prompt names the pictures in the order they come and gives each
    camera; by the formula it states, the pick-side depth at the pixel of brick 0's top
    centre (from above, the waiting arm hides it) is that point. A state prompt has no such
    section."""
    state = scene_state(scene)
    none = ToolTier.NONE  # the check tier adds the deproject tool too
    spec, both = agent_specs(none)[0], agent_specs(none, Observation.BOTH)[0]
    assert agent_specs(observation=Observation.BOTH)[0].tools[-1] == "deproject"
    view = StateView.of(state, TaskMemory(), spec.scope)
    shown = render_prompt(both, view, TaskMemory(), Tolerances())
    plain = render_prompt(spec, view, TaskMemory(), Tolerances())
    assert "## Cameras" not in plain
    section = f"## Cameras\n{cameras_text(Observation.BOTH)}\n\n"
    assert shown.replace(section, "") == plain  # all it adds
    assert f"in this order: {', '.join(SHOWN_NAMES)}." in shown
    cameras = {str(c["name"]): c for c in prompt_cameras(shown)}
    assert set(cameras) == set(CAMERAS)
    side = cameras["pick_side"]
    depth = read_depth(depth_png(capture(scene.client, CAMERAS["pick_side"]).depth_m))
    centre, _ = scene.brick_pose(0)
    u, v, _ = CAMERAS["pick_side"].project((centre[0], centre[1], centre[2] + 0.03))
    d = float(depth[round(v), round(u)])
    fx, fy, cx, cy = (float(side[k]) for k in ("fx", "fy", "cx", "cy"))  # type: ignore[arg-type]
    pose = side["pose"]
    assert isinstance(pose, dict)
    in_camera = ((round(u) - cx) / fx * d, (round(v) - cy) / fy * d, d)
    world = Rotation.from_quat(pose["quat_xyzw"]).apply(in_camera) + np.array(pose["position_m"])
    assert math.dist(world[:2], centre[:2]) < 0.006  # within the pixel, rounded
    assert world[2] == pytest.approx(centre[2] + 0.03, abs=0.001)


def scene_state(scene: Scene) -> WorldState:
    """The exactly measured state of the layout scene, the goal a pyramid."""
    sensor = Sensor(scene, NOISE["none"], trial_seed=0)
    return sensor.perceive(load_pattern("pyramid", SceneSpec()), Progress())
