"""`actionreasoning report` on real runs: tables, plots, stage grids, GIFs, and the HTML page
as Chromium renders it."""

from __future__ import annotations

import csv
import json
import os
import shutil
import statistics
from pathlib import Path

import imageio.v3 as iio
import pytest
from conftest import SMALL_PATTERN, assert_clean_error, cli

from actionreasoning.runs.courses import FINISHED_BUILD as FINISHED

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Two methods on the small pattern, with snapshots and videos, under precise physics
    (where the classical script succeeds too, so every cell of the table has figures)."""
    root = tmp_path_factory.mktemp("runs")
    pattern = root / "small.json"
    pattern.write_text(json.dumps(SMALL_PATTERN))
    made = []
    for method, trials in (("classical", "2"), ("agents", "1")):
        out = root / method
        result = cli(
            "eval", "--method", method, "--pattern", str(pattern), "--trials", trials,
            "--out", str(out), "--snapshots", "--video", "--physics", "precise",
        )  # fmt: skip
        assert result.returncode == 0, result.stderr
        made.append(out)
    return made


@pytest.fixture(scope="module")
def report(runs: list[Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("report")
    result = cli("report", *map(str, runs), "--out", str(out), "--gif")
    assert result.returncode == 0, result.stderr
    assert "report.html" in result.stdout
    return out


def summary_of(run: Path) -> dict:
    return json.loads((run / "summary.json").read_text())


@pytest.mark.slow
def test_the_tables_hold_each_runs_figures(runs: list[Path], report: Path) -> None:
    rows = list(csv.DictReader((report / "table.csv").open()))
    assert [(r["method"], r["pattern"]) for r in rows] == [
        ("classical, precise", "small"), ("classical, precise", "Average"),
        ("agents (builtin, tools check), precise", "small"),
        ("agents (builtin, tools check), precise", "Average"),
    ]  # fmt: skip
    for run, row in zip(runs, rows[::2], strict=True):
        summary = summary_of(run)
        assert (int(row["successes"]), int(row["trials"])) == (
            summary["successes"],
            summary["trials"],
        )
        for metric in ("rotation_error_deg", "center_offset_cm", "iou"):
            assert float(row[f"{metric}_mean"]) == pytest.approx(
                summary["successful"][metric]["mean"]
            )
    markdown = (report / "table.md").read_text()
    assert "| small: Rot. Err ↓ |" in markdown
    assert "| agents (builtin, tools check), precise |" in markdown
    success = "2/2 (100 %, 95 % CI 34–100 %)"
    assert f"| classical, precise | {success} | {success} |" in markdown
    latex = (report / "table.tex").read_text()
    assert r"\multicolumn{3}{c}{\textbf{small}}" in latex
    assert latex.count(r"\\") == 4 + 4 + 3  # Table I, over all trials; success
    assert r"2/2 (100 \%, 95 \% CI 34--100 \%)" in latex


@pytest.mark.slow
def test_plots_grids_and_gifs_are_real_pictures(report: Path) -> None:
    for name in ("errors.png", "success.png", "stages_small.png"):
        image = iio.imread(report / name)
        assert image.shape[0] > 200 and image.shape[1] > 300 and image.std() > 10
    gifs = sorted((report / "gifs").glob("*.gif"))
    assert [g.name for g in gifs] == [
        "agents_builtin_tools_check_precise_small_trial_000.gif",
        "classical_precise_small_trial_000.gif",
        "classical_precise_small_trial_001.gif",
    ]
    frames = iio.imread(gifs[0], index=None)
    assert len(frames) == 3 * 7 + 1  # every stage of every brick, then the final frame
    assert not (report / "llm_cost.png").exists()  # no run called a model


@pytest.mark.slow
def test_the_html_page_renders_in_chromium(runs: list[Path], report: Path) -> None:
    if CHROMIUM is None:
        if os.environ.get("ACTIONREASONING_REQUIRE_BROWSER"):
            pytest.fail("Chromium is not installed, and this run requires the browser test")
        pytest.skip("Chromium is not installed (apt-get install chromium); .ci/run installs it")
    from playwright.sync_api import sync_playwright

    page_path = report / "report.html"
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=CHROMIUM,
            args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"],
        )
        page = browser.new_page()
        page.goto(page_path.as_uri())
        page.wait_for_load_state("load")
        rows = page.locator("#table-i tbody tr").all()
        cells = [row.locator("td").all_inner_texts() for row in rows]
        images = page.eval_on_selector_all(
            "img", "all => all.map(i => [i.complete, i.naturalWidth, i.naturalHeight])"
        )
        shown = page.locator("img").first.bounding_box()
        videos = page.eval_on_selector_all("video", "all => all.map(v => v.getAttribute('src'))")
        played = page.evaluate(
            """async () => {
                const video = document.querySelector('video');
                video.muted = true;
                await video.play();
                await new Promise(done => setTimeout(done, 1500));
                return [video.readyState, video.currentTime, video.error === null];
            }"""
        )
        browser.close()
    classical = summary_of(runs[0])["successful"]
    assert [row[0] for row in cells] == [
        "classical, precise",
        "agents (builtin, tools check), precise",
    ]
    metrics = (("rotation_error_deg", 1, 3), ("center_offset_cm", 1, 3), ("iou", 100, 2))
    shown_as = [
        [f"{classical[m][key] * scale:.{digits}f}" for key in ("mean", "ci_low", "ci_high")]
        for m, scale, digits in metrics
    ]
    assert [cell.splitlines() for cell in cells[0][1:4]] == [
        [mean, f"[{low}, {high}]"] for mean, low, high in shown_as
    ]  # each mean over its bootstrap interval
    assert len(images) == 3 + 1 + 3  # three plots, one stage grid, three GIFs
    assert all(done and width > 0 and height > 0 for done, width, height in images)
    assert shown is not None and shown["width"] > 100 and shown["height"] > 100
    assert 'src="data:image/png;base64,' in page_path.read_text()  # no picture to fetch
    assert videos == [
        "videos/classical_precise_small_trial_000.mp4",
        "videos/classical_precise_small_trial_001.mp4",
        "videos/agents_builtin_tools_check_precise_small_trial_000.mp4",
    ]  # copied beside the page; all succeeded, so in table order
    ready, played_s, no_error = played
    assert ready >= 2 and played_s > 0.5 and no_error  # Chromium decodes and plays the MP4


def lines_of(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "results.jsonl").read_text().splitlines()]


def table_after(text: str, heading: str) -> list[str]:
    """The rows of the markdown table that follows ``heading``."""
    block = text.split(heading, 1)[1].split("\n\n", 2)[1]
    return block.splitlines()[2:]


@pytest.mark.slow
def test_the_course_plot_is_a_png_of_its_size(report: Path) -> None:
    path = report / "courses.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = iio.imread(path)
    assert image.shape == (418, 924, 4)  # 8.4 x 3.8 in at 110 dpi: 3.6 in, a row of legend
    assert image.std() > 10
    assert "![Errors per course](courses.png)" in (report / "table.md").read_text()


@pytest.mark.slow
def test_the_course_tables_hold_a_hand_computation_from_the_lines(
    runs: list[Path], report: Path
) -> None:
    """The small pattern's two courses (bottoms at 0 and 6 cm), pooled over each run's
    trials; bricks before the first one out of 2 cm and 5 deg; simulated time per brick."""
    markdown, html = (report / "table.md").read_text(), (report / "report.html").read_text()
    labels = ["classical, precise", "agents (builtin, tools check), precise"]
    for run, label in zip(runs, labels, strict=True):
        lines = lines_of(run)
        by_course: dict[int, list[dict]] = {}
        for line in lines:
            for brick in line["bricks"]:
                bottom = brick["target_position"][2] - brick["size"][2] / 2
                by_course.setdefault(round(bottom / 0.06), []).append(brick)
        rows = []
        for course, bricks in sorted(by_course.items()):
            cells = [str(course), str(len(bricks))]
            for field, scale, digits in (
                ("center_offset_cm", 1, 3), ("rotation_error_deg", 1, 3), ("iou", 100, 2),
            ):  # fmt: skip
                values = [b[field] * scale for b in bricks]
                mean, std = statistics.fmean(values), statistics.pstdev(values)
                cells.append(f"{mean:.{digits}f} ± {std:.{digits}f}")
            rows.append(cells)
        assert [len(by_course[0]), len(by_course[1])] == [2 * len(lines), len(lines)]
        shown = table_after(markdown, f"Per course of {label} on small (0 on the ground)")
        assert shown == ["| " + " | ".join(cells) + " |" for cells in rows]
        html_rows = "".join(f"<td>{cell}</td>" for cells in rows for cell in cells)
        assert html_rows in html.replace("</tr>\n<tr>", "")

        before = []
        for line in lines:
            ok = [
                b["center_offset_cm"] <= 2 and b["rotation_error_deg"] <= 5 for b in line["bricks"]
            ]
            before.append([*ok, False].index(False))
        step_s = json.loads((run / "run.json").read_text())["config"]["physics"]["time_step_s"]
        seconds = sum(line["sim_steps"] for line in lines) * step_s
        finished = [not line["failure"] or line["failure"]["reason"] in FINISHED for line in lines]
        assert all(finished)  # every build finished: each set its 3 bricks down
        set_down = [len(line["bricks"]) for line in lines]
        within = [line["bricks_placed"] for line in lines]
        per_set_down, per_within = seconds / sum(set_down), seconds / sum(within)
        pace = (
            f"| {label} | small | {statistics.fmean(set_down):.2f} of 3 | "
            f"{statistics.fmean(within):.2f} of 3 | {statistics.fmean(before):.2f} of 3 | "
            f"{per_set_down:.1f} | {3600 / per_set_down:.0f} | {per_within:.1f} |"
        )
        assert pace in markdown
        assert pace.replace(" | ", "</td><td>")[2:-2] in html


def test_a_run_of_an_earlier_version_gets_its_cycle_time_and_one_course_no_plot(
    tmp_path: Path,
) -> None:
    """Its run.json gives the success rule in words, so bricks before the first failure are
    not counted; it records the physics, so the cycle time is. All bricks on the ground: a
    table of one course and no plot."""
    from test_courses import brick
    from test_run_dir import EARLIER_MANIFEST, result

    from actionreasoning.trial.provenance import Provenance
    from actionreasoning.world.physics import PRECISE

    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(json.dumps(EARLIER_MANIFEST))
    lines = [
        result(trial).model_copy(
            update={"bricks": (brick(0.03, 0.5), brick(0.03, 1.5)), "bricks_placed": 2,
                    "sim_steps": 4800}
        )
        for trial in range(2)
    ]  # fmt: skip
    exclude = {*Provenance.model_fields, "tools"}
    (run / "results.jsonl").write_text(
        "".join(json.dumps(r.model_dump(mode="json", exclude=exclude)) + "\n" for r in lines)
    )
    outcome = cli("report", str(run), "--out", str(tmp_path / "report"))
    assert outcome.returncode == 0, outcome.stderr
    table = (tmp_path / "report" / "table.md").read_text()
    assert PRECISE.time_step_s == 1 / 480  # two trials of 10 s, four bricks placed
    row = "| agents (builtin, tools solve), precise | pyramid | 2.00 of 2 | 2.00 of 2 | – |"
    assert f"{row} 5.0 | 720 | 5.0 |" in table  # both built: all their bricks set down
    # offsets 0.5, 1.5, 0.5, 1.5: mean 1, std 0.5; rotation half of them, IoU 1 - offset/10
    assert table_after(table, "Per course of agents") == [
        "| 0 | 4 | 1.000 ± 0.500 | 0.500 ± 0.250 | 90.00 ± 5.00 |"
    ]
    assert not (tmp_path / "report" / "courses.png").exists()
    assert "courses.png" not in table


def test_a_directory_without_results_is_refused(tmp_path: Path) -> None:
    assert_clean_error(cli("report", str(tmp_path), cwd=tmp_path), "holds no results.jsonl")


@pytest.mark.parametrize("name", ["run.json", "results.jsonl"])
def test_a_run_file_that_is_a_directory_is_named_as_such(tmp_path: Path, name: str) -> None:
    (tmp_path / "results.jsonl").write_text("")
    (tmp_path / "run.json").write_text("{}")
    for path in tmp_path.iterdir():
        if path.name == name:
            path.unlink()
            path.mkdir()
    assert_clean_error(
        cli("report", str(tmp_path), cwd=tmp_path),
        f"{tmp_path / name} is not a regular file: not a {name} eval writes",
    )


def test_a_report_that_refuses_its_input_creates_nothing(tmp_path: Path) -> None:
    run, here, out = tmp_path / "run", tmp_path / "here", tmp_path / "new" / "report"
    run.mkdir()
    here.mkdir()
    assert_clean_error(cli("report", str(run), cwd=here), "holds no results.jsonl")
    assert_clean_error(cli("report", str(run), "--out", str(out)), "holds no results.jsonl")
    assert not any(here.iterdir()) and not out.parent.exists()


def test_llm_cost_and_the_failure_taxonomy_are_reported(tmp_path: Path) -> None:
    """A run whose results carry usage per agent (as an LLM run writes them) gets the plot;
    failures are counted by reason with its meaning and an example trial."""
    from test_run_dir import manifest, result

    from actionreasoning.reasoners.backend import LLMConfig
    from actionreasoning.records import FailureCode, LLMUsage
    from actionreasoning.world.physics import PRECISE

    run = tmp_path / "run"
    run.mkdir()
    gemma = manifest(llm=LLMConfig(spec="openai:gemma"), physics=PRECISE)
    (run / "run.json").write_text(gemma.model_dump_json())
    usage = {
        "pre_grasp": LLMUsage(calls=2, prompt_tokens=9000, completion_tokens=300, latency_s=40.0),
        "placement": LLMUsage(calls=4, prompt_tokens=20000, completion_tokens=900, latency_s=90.0),
    }
    lines = [
        result(trial, success=trial == 0).model_copy(
            update={"llm": "openai:gemma", "llm_usage_by_agent": usage}
        )
        for trial in range(3)
    ]
    (run / "results.jsonl").write_text("".join(r.model_dump_json() + "\n" for r in lines))
    outcome = cli("report", str(run), "--out", str(tmp_path / "report"))
    assert outcome.returncode == 0, outcome.stderr
    image = iio.imread(tmp_path / "report" / "llm_cost.png")
    assert image.shape[1] > 500 and image.std() > 10
    table = (tmp_path / "report" / "table.md").read_text()
    success = "1/3 (33 %, 95 % CI 6–79 %)"  # Wilson: 0.0615 to 0.7923
    assert f"| agents (openai:gemma, tools check), precise | {success} | {success} |" in table
    meaning = FailureCode.MISPLACED.meaning
    row = (
        f"| agents (openai:gemma, tools check), precise | pyramid | `misplaced` | physics | "
        f"{meaning} | 2 | trial 1: "
    )
    assert row + "brick 3 |" in table
    assert "| agents (openai:gemma, tools check), precise | pyramid | 0 | 2 |" in table
    html = (tmp_path / "report" / "report.html").read_text()
    cells = f"<code>misplaced</code></td><td>physics</td><td>{meaning}</td><td>2</td>"
    assert cells + "<td>trial 1: brick 3" in html
    assert "<td>pyramid</td><td>0</td><td>2</td></tr>" in html
