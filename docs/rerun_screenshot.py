r"""Screenshot a trial's Rerun recording as the Rerun viewer shows it, with no display or GPU.

Makes ``docs/rerun_recording.png``, from the repository's root, with the ``test`` extras
installed and Chromium on the PATH::

    actionreasoning eval --method agents --pattern pyramid --trials 2 --seed 0 --rerun \
        --out runs/shot
    python docs/rerun_screenshot.py runs/shot/rerun/trial_001.rrd --time 66 \
        --out docs/rerun_recording.png

The rerun-sdk wheel's ``rerun`` binary serves its web viewer and the recording, with a
layout (a blueprint) made here; headless Chromium draws the viewer with its software
renderer (WebGL on SwiftShader); the time cursor is set by typing into the viewer's time
field. (The native viewer's ``--headless`` mode needs a graphics adapter that Rerun can
render with; Mesa's llvmpipe, over GL, is not one: "Failed to get render context".)
"""

from __future__ import annotations

import argparse
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from urllib.parse import quote

import rerun as rr
import rerun.blueprint as rrb
import rerun_cli
from playwright.sync_api import Error as PlaywrightError
from playwright.sync_api import Page, sync_playwright

APPLICATION_ID = "actionreasoning"  # as the recordings have it (recording/rerun_log.py)
TIMELINE = "sim"
CHROMIUM_ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]
#: The camera: beside the pyramid, the arm behind it, the spare bricks on the left.
EYE = (1.15, 0.45, 0.53)
LOOK_AT = (0.22, 0.15, 0.13)
TIME_PANEL_PX = 28  # the collapsed time panel's height, at the bottom


def blueprint() -> rrb.Blueprint:
    """The 3D scene and three plots above, the agents' and gates' log below."""
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(
                    origin="/world",
                    name="world: bricks, ghost targets, arm, gripper",
                    overrides={
                        "/world/targets": rr.Boxes3D.from_fields(show_labels=False).visualizer()
                    },
                    eye_controls=rrb.EyeControls3D(
                        position=EYE, look_target=LOOK_AT, eye_up=(0.0, 0.0, 1.0)
                    ),
                ),
                rrb.Vertical(
                    rrb.TimeSeriesView(origin="/forces", name="pad forces (N)"),
                    rrb.TimeSeriesView(origin="/slip", name="held brick's slip (m/s)"),
                    rrb.TimeSeriesView(origin="/offset_cm", name="offset from target (cm)"),
                ),
                column_shares=[3, 2],
            ),
            rrb.TextLogView(
                origin="/",
                contents=["/agents/**", "/stages"],
                name="agents, gates and stages",
                columns=rrb.TextLogColumns(
                    timeline_columns=[rrb.encodings.TimelineColumn(TIMELINE, visible=False)],
                    text_log_columns=["loglevel", "body"],
                ),
            ),
            row_shares=[3, 2],
        ),
        rrb.TimePanel(state="collapsed", timeline=TIMELINE, play_state="paused"),
        rrb.TopPanel(state="hidden"),
        rrb.BlueprintPanel(state="hidden"),
        rrb.SelectionPanel(state="hidden"),
    )


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def chromium() -> str:
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if path is None:
        sys.exit("needs Chromium on the PATH (apt-get install chromium)")
    return path


def settle(page: Page, *, at_least_s: float, timeout_s: float = 120.0) -> bytes:
    """Wait until the viewer draws the same picture twice running; return it."""
    time.sleep(at_least_s)
    previous, deadline = b"", time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        shot = page.screenshot()
        if shot == previous:
            return shot
        previous = shot
        time.sleep(2.0)
    sys.exit(f"the viewer was still changing after {timeout_s:.0f} s")


def seek(page: Page, time_s: float, width: int, height: int, tries: int = 3) -> None:
    """Type ``time_s`` into the time field, at the right end of the collapsed time panel,
    until the time panel changes (a click can go unseen while the viewer is busy)."""
    panel = {"x": 0, "y": height - TIME_PANEL_PX, "width": width, "height": TIME_PANEL_PX}
    before = page.screenshot(clip=panel)
    for _ in range(tries):
        page.mouse.click(width - 100, height - TIME_PANEL_PX / 2)
        time.sleep(1.0)
        page.keyboard.press("Control+A")
        page.keyboard.type(f"{time_s}s")
        page.keyboard.press("Enter")
        settle(page, at_least_s=2.0)
        if page.screenshot(clip=panel) != before:
            return
    sys.exit(f"could not move the time cursor to {time_s} s")


def screenshot(rrd: Path, out: Path, time_s: float, width: int, height: int) -> None:
    """Serve ``rrd`` with the layout, open the viewer, seek to ``time_s``, save ``out``."""
    web, grpc = free_port(), free_port()
    with tempfile.TemporaryDirectory() as tmp:
        layout = Path(tmp) / "layout.rbl"
        blueprint().save(APPLICATION_ID, layout)
        # The binary itself: the `rerun` script is a wrapper that leaves it running if killed.
        binary = Path(rerun_cli.__file__).with_name("rerun")
        serve = ["--serve-web", "--web-viewer-port", str(web), "--port", str(grpc)]
        server = subprocess.Popen(
            [str(binary), *serve, str(rrd), str(layout)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            source = quote(f"rerun+http://127.0.0.1:{grpc}/proxy", safe="")
            url = f"http://127.0.0.1:{web}/?url={source}&renderer=webgl&persist=0"
            with sync_playwright() as playwright:
                browser = playwright.chromium.launch(
                    executable_path=chromium(), headless=True, args=CHROMIUM_ARGS
                )
                page = browser.new_page(viewport={"width": width, "height": height})
                open_viewer(page, url)
                settle(page, at_least_s=10.0)
                seek(page, time_s, width, height)
                page.dispatch_event("canvas", "mouseleave")  # no hover highlight
                out.write_bytes(settle(page, at_least_s=2.0))
                browser.close()
        finally:
            server.terminate()
            server.wait()


def open_viewer(page: Page, url: str, timeout_s: float = 30.0) -> None:
    """Open ``url`` once the server answers."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            page.goto(url)
            return
        except PlaywrightError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.5)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rrd", type=Path, help="a recording: rerun/trial_NNN.rrd of eval --rerun")
    parser.add_argument("--time", type=float, default=0.0, help="the simulated second to show")
    picture = Path(__file__).with_name("rerun_recording.png")
    parser.add_argument("--out", type=Path, default=picture, help=f"default: {picture}")
    parser.add_argument("--width", type=int, default=1280, help="of the page, in pixels")
    parser.add_argument("--height", type=int, default=720, help="of the page, in pixels")
    args = parser.parse_args()
    if not args.rrd.is_file():
        sys.exit(f"no recording at {args.rrd}")
    screenshot(args.rrd.resolve(), args.out, args.time, args.width, args.height)


if __name__ == "__main__":
    main()
