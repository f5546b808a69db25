"""The results pages cannot drift from the committed run files: the 3 vs 1 study page (``docs/results/football-3v1.md``)
is rebuilt from its run files by ``benchmarks/results_pages.py`` and compared byte for byte, a changed run file shows
up, and the report the page copies from (``football-stage-f/learning_speed.md``) re-generates from its ``runs.csv``."""

import shutil
from pathlib import Path

import pytest

DOCS = Path(__file__).parent.parent / "docs"
RESULTS = DOCS / "results"
PAGE = "football-3v1"


@pytest.fixture(scope="module")
def pages(load_benchmark_script):
    return load_benchmark_script("results_pages")


def blocks(text):
    """The generated blocks of a page: ``{command: lines}``."""
    found, lines = {}, text.splitlines()
    for index, line in enumerate(lines):
        if line.startswith("<!-- results_pages: "):
            end = lines.index("<!-- /results_pages -->", index)
            found[line] = lines[index + 1 : end]
    return found


def test_the_3v1_page_rebuilds_from_its_run_files(pages, tmp_path):
    assert pages.main(["--pages", PAGE, "--out", str(tmp_path)]) == 0
    committed = (RESULTS / f"{PAGE}.md").read_text()
    assert (tmp_path / "results" / f"{PAGE}.md").read_text() == committed
    table = blocks(committed)[f"<!-- results_pages: rows {PAGE} -->"]
    # the rows hold the numbers, not an empty block: seed 1 (football-probe) and seeds 2-3 (football-stage-f), at 2M
    row = "| 3 vs 1 (1.0) | SAEIR_PPO | 3 | 45.0, 64.0, 62.0 | 57.00\u00a0±\u00a08.52 | 57.00 [45.00,\u00a064.00] | 0.5M |"
    assert row in "\n".join(table)
    assert len(table) == 4


def test_a_changed_run_file_shows_on_the_page(pages, tmp_path):
    docs = tmp_path / "docs"
    shutil.copytree(RESULTS, docs / "results", ignore=shutil.ignore_patterns("*.png"))
    assert pages.main(["--docs", str(docs), "--pages", PAGE, "--check"]) == 0
    runs = docs / "results" / "football-stage-f" / "3v1" / "runs.csv"
    lines = runs.read_text().splitlines()
    header = lines[0].split(",")
    last = max(range(1, len(lines)), key=lambda i: int(lines[i].split(",")[header.index("timesteps")]))
    cells = lines[last].split(",")
    cells[header.index("success_mean")] = "0.99"  # one seed's final success
    lines[last] = ",".join(cells)
    runs.write_text("\n".join(lines) + "\n")
    assert pages.main(["--docs", str(docs), "--pages", PAGE, "--check"]) == 1
    assert pages.main(["--docs", str(docs), "--pages", PAGE]) == 0  # rewritten: now it agrees with the changed file
    assert "99.0" in (docs / "results" / f"{PAGE}.md").read_text()
    assert pages.main(["--docs", str(docs), "--pages", PAGE, "--check"]) == 0


def test_the_copied_report_regenerates_from_its_runs(load_benchmark_script, tmp_path, monkeypatch):
    speed = load_benchmark_script("learning_speed")
    monkeypatch.chdir(DOCS.parent)  # the report names its inputs as given: from the repository root, as report.sh does
    folder = "docs/results/football-stage-f"
    runs = ["docs/results/football-probe/runs.csv", f"{folder}/3v1/runs.csv", f"{folder}/counterattack/runs.csv"]
    assert speed.main(["--out", str(tmp_path), *runs]) == 0
    assert (tmp_path / "learning_speed.md").read_text() == (DOCS.parent / folder / "learning_speed.md").read_text()


def test_every_study_has_a_page_in_the_summary_and_the_toctree(pages):
    summary = (DOCS / "results.md").read_text()
    for name in pages.STUDIES:
        assert (RESULTS / f"{name}.md").is_file()
        assert f"results/{name}\n" in summary  # the toctree
        assert f"(results/{name}.md)" in summary  # a link


def test_a_page_without_its_block_end_is_refused(pages, tmp_path):
    with pytest.raises(SystemExit, match="has no"):
        pages.rebuild("<!-- results_pages: rows football-3v1 -->\n| stale |\n", RESULTS)


def test_checkpoint_tables_follow_the_longer_runs(pages):
    # navigation-calibrated holds 20M-env-step runs and two 15-seed arms of 1M: the arms have rows, but no line in the
    # table of coverage every 2M env steps, where every cell after 0 would be "-"
    study = [("navigation-calibrated", row) for row in pages.STUDIES["navigation-calibrated"].rows]
    methods = [line.split(" | ")[1] for line in pages.rows_table(study, RESULTS, summary=False)[2:]]
    assert methods.count("MSHG-only") == 1 and "MSHG-only, no Gumbel noise" in methods
    table = pages.checkpoints_table("navigation-calibrated", RESULTS)
    assert [line.split(" | ")[1] for line in table[2:]] == ["MAPPO", "MAPPO", "SAEIR_PPO"]


def test_a_running_study_page_is_rebuilt_too(pages, tmp_path, capsys):
    # a study still running (counterattack-4m) has no rows yet, only copies of its report's tables: it is a results
    # page all the same, found by its generated blocks
    assert RESULTS / "counterattack-4m.md" in pages.pages(DOCS)
    docs = tmp_path / "docs"
    shutil.copytree(RESULTS, docs / "results", ignore=shutil.ignore_patterns("*.png"))
    shutil.copy(DOCS / "results.md", docs / "results.md")
    running = docs / "results" / "running-study.md"
    block = ["<!-- results_pages: copy football-probe/random_baseline.md -->", "| stale |", "<!-- /results_pages -->"]
    running.write_text("\n".join(["# Running", "", *block, ""]))
    assert pages.main(["--docs", str(docs), "--check"]) == 1
    assert pages.main(["--docs", str(docs), "--pages", "running-study"]) == 0
    assert "| stale |" not in running.read_text()
    assert "grf-counterattack-easy | success | 500" in running.read_text()
    assert pages.main(["--docs", str(docs), "--check"]) == 0
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit_info:
        pages.main(["--docs", str(docs), "--pages", "no-such-study"])
    assert exit_info.value.code == 2 and "no study page no-such-study; pages: " in capsys.readouterr().err


def test_a_row_of_a_file_with_two_tasks_names_its_task(pages):
    # navigation-full-budget's runs.csv holds N=3 and N=4: a row reads the one its task_id names, and a row without one
    # is refused rather than mixing the two
    source = ("navigation-full-budget/runs.csv:mappo",)
    n4 = pages.Row(pages.NAV4, "MAPPO", source, "2.1", task_id="cn-sparse-n4")
    assert {row["task"] for row in pages.row_runs(n4, RESULTS)} == {"cn-sparse-n4"}
    with pytest.raises(SystemExit, match="hold tasks cn-sparse-n3, cn-sparse-n4: name the row's task_id"):
        pages.row_runs(pages.Row(pages.NAV4, "MAPPO", source, "2.1"), RESULTS)
    with pytest.raises(SystemExit, match="no rows of task 'cn-sparse-n5'"):
        pages.row_runs(n4._replace(task_id="cn-sparse-n5"), RESULTS)


def test_the_summary_figures_are_drawn_from_the_run_files(pages, tmp_path):
    docs = tmp_path / "docs"
    shutil.copytree(RESULTS, docs / "results", ignore=shutil.ignore_patterns("*.png"))
    shutil.copy(DOCS / "results.md", docs / "results.md")
    assert pages.main(["--docs", str(docs), "--pages", PAGE, "--figures"]) == 0
    for name in ("navigation_seeds.png", "football_seeds.png"):
        assert (docs / "results" / "summary" / name).stat().st_size > 10_000
