"""The documentation: the site builds with ``mkdocs build --strict`` (a broken link, anchor or API reference fails
it), the API reference covers the public names, and the README stays short and names CI's test command."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import aca_warp

REPO = Path(__file__).resolve().parent.parent
README_MAX_LINES = 150
ROLE = re.compile(r":(?:func|class|mod|data|meth|attr|exc|obj):(?:`|<code>)")  # as written, as rendered


def _mkdocs_build(config: Path, site: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    cmd = [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(config), "-d", str(site)]
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)


def test_site_builds_strict(tmp_path: Path) -> None:
    """The whole site, API reference included, builds without a warning; the docstrings' Sphinx roles are turned
    into links or code (docs/api/sphinx_roles.py), none is left raw."""
    site = tmp_path / "site"
    out = _mkdocs_build(REPO / "mkdocs.yml", site)
    problems = [line for line in out.stderr.splitlines() if line.startswith(("WARNING", "ERROR", "Aborted"))]
    assert out.returncode == 0, "\n".join(problems) or out.stderr[-4000:]
    assert (site / "index.html").is_file()
    api = sorted((site / "api").rglob("*.html"))
    assert len(api) >= 9
    raw = [f"{p.relative_to(site)}: {m.group(0)}" for p in api for m in ROLE.finditer(p.read_text())]
    assert raw == []
    scene = (site / "api" / "scene" / "index.html").read_text()
    assert 'id="aca_warp.scene.Scene"' in scene


def test_strict_build_fails_on_a_broken_anchor(tmp_path: Path) -> None:
    """The repository's settings (validation of links and anchors) turn a link to a missing heading into a failed
    build: the check of the test above can fail."""
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "index.md").write_text("# Home\n\nSee [the other page](other.md#no-such-heading).\n")
    (docs / "other.md").write_text("# Other\n\n## A heading\n")
    config = tmp_path / "mkdocs.yml"
    config.write_text(
        f"INHERIT: {REPO / 'mkdocs.yml'}\ndocs_dir: {docs}\nnav: [index.md, other.md]\nplugins: [search]\n"
    )
    out = _mkdocs_build(config, tmp_path / "site")
    assert out.returncode != 0
    assert "no-such-heading" in out.stderr
    (docs / "index.md").write_text("# Home\n\nSee [the other page](other.md#a-heading).\n")
    assert _mkdocs_build(config, tmp_path / "site").returncode == 0


def test_api_reference_covers_the_public_names() -> None:
    """Every name ``from aca_warp import ...`` offers is linked from the API index, and its module is rendered on
    one of the API pages."""
    pages = {p.name: p.read_text() for p in (REPO / "docs" / "api").glob("*.md")}
    rendered = {m for text in pages.values() for m in re.findall(r"^::: ([\w.]+)", text, re.MULTILINE)}
    missing_links = [n for n, mod in aca_warp._PUBLIC.items() if f"[`{n}`][{mod}.{n}]" not in pages["index.md"]]
    missing_modules = sorted({mod for mod in aca_warp._PUBLIC.values()} - rendered)
    assert missing_links == []
    assert missing_modules == []


def _ci_test_command() -> str:
    lines = (REPO / ".ci" / "run").read_text().splitlines()
    tests = [line.strip() for line in lines if "pytest" in line and not line.lstrip().startswith("#")]
    assert len(tests) == 1, tests
    return tests[0]


def test_readme_is_short_and_names_ci_test_command() -> None:
    readme = (REPO / "README.md").read_text()
    assert len(readme.splitlines()) <= README_MAX_LINES
    command = _ci_test_command()
    assert shlex.split(command)[:3] == ["python3", "-m", "pytest"]
    assert re.search(rf"^{re.escape(command)}$", readme, re.MULTILINE), command


def test_readme_links_name_files_of_the_repository() -> None:
    readme = (REPO / "README.md").read_text()
    targets = [t.split("#")[0] for t in re.findall(r"\]\(([^)\s]+)\)", readme) if "://" not in t]
    assert targets
    missing = [t for t in targets if t and not (REPO / t).exists()]
    assert missing == []


def test_quickstart_timing_runs_the_readme_command():
    """scripts/time_quickstart.py times the README's quick-start command as written: the install, then the main
    job (the command's last part, which writes a run file)."""
    from scriptload import load_script

    qs = load_script("time_quickstart")
    command = qs.quickstart_command((Path(__file__).resolve().parent.parent / "README.md").read_text())
    setup, job = command.rsplit(" && ", 1)
    assert 'pip install -e ".[test]"' in setup and job.startswith("aca-warp hf ") and " -o " in job


def test_suite_timing_beside_a_second_suite(tmp_path: Path) -> None:
    """scripts/time_tests.py --beside starts a second suite at the same moment as the timed one and reports both:
    each run's own exit code, output, wall and CPU time (here two small commands burning 0.4 s and 0.05 s of CPU,
    started together); the Markdown names the second suite's figures."""
    from scriptload import load_script

    tt = load_script("time_tests")
    assert tt.parse_args(["--beside", "-n", "2"]).beside and not tt.parse_args([]).beside
    burn = "import time\nt = time.process_time()\nwhile time.process_time() - t < {s}: pass\nprint('{n} passed')\n"
    runs = [
        (tmp_path, [sys.executable, "-c", burn.format(s=0.4, n=3)], dict(os.environ)),
        (tmp_path, [sys.executable, "-c", burn.format(s=0.05, n=1) + "raise SystemExit(1)"], dict(os.environ)),
    ]
    timed, other = tt._suites(runs, 120.0)
    assert (timed["exit_code"], other["exit_code"]) == (0, 1)
    assert tt.counts(timed["output"])["passed"] == 3 and tt.counts(other["output"])["passed"] == 1
    assert timed["cpu_s"] >= 0.4 > other["cpu_s"] >= 0.05  # each its own process tree's CPU time
    assert timed["wall_s"] > 0 and other["wall_s"] > 0
    r = {
        "command": "python3 -m pytest -q -n auto tests", "commit": "abc1234", "date": "2026-01-01 00:00",
        "machine": "a test machine", "kernel_cache": "warm", "load_before": 0.1, "load_after": 2.0,
        "passed": 3, "skipped": 0, "failed": 0, "errors": 0, "failures": [], "wall_s": 200.0, "cpu_s": 280.0,
        "beside": {"exit_code": 0, "passed": 990, "skipped": 1, "failed": 0, "errors": 0, "wall_s": 299.6,
                   "cpu_s": 281.0},
    }  # fmt: skip
    page = tt.markdown(r)
    assert "| 3 | 0 | 0 | 3 min 20 s | 4 min 40 s |" in page
    assert (
        "Beside a second copy of the suite" in page and "990 passed, 0 failed, 5 min 0 s wall, 4 min 41 s CPU" in page
    )  # 299.6 s rounded as a whole: not "4 min 60 s"
    assert "kernel modules added" not in page
    assert "kernel cache warm, 62 kernel modules added to it during the run" in tt.markdown(
        {**r, "kernels_compiled": 62}
    )
    assert tt.cached_modules({"WARP_CACHE_PATH": str(tmp_path / "none")}) == 0
    (tmp_path / "cache" / "1.19.0" / "wp_a_1").mkdir(parents=True)
    assert tt.cached_modules({"WARP_CACHE_PATH": str(tmp_path / "cache")}) == 1
    del r["beside"]
    assert "Beside" not in tt.markdown(r)
