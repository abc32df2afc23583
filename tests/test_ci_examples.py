"""examples/ci/: the GitHub Actions workflow and the GitLab job, run locally.

The workflow's YAML is parsed and its steps run in order as GitHub would run them: each ``run:``
block through ``bash --noprofile --norc -eo pipefail`` (the workflow's ``shell: bash``) with the
workflow's ``env:`` (plus the test's overrides) and ``GITHUB_STEP_SUMMARY`` set, each ``if:``
evaluated (only the forms the example uses are understood; another one fails the test), and a
``uses:`` step checked for what it would need (the upload's path exists).

* The default test stands in for the install step with this checkout's environment and runs
  the other steps on a tiny plugin made in a temporary folder (a toy case of tests/fake_cases.py
  declared through an entry point, as pip would install it) and the reference solver, in
  seconds.  The GitLab job must run the same commands with the same variables (a default
  test); its script runs the same way in a slow test.
* The slow test runs every step for real: a fresh virtual environment, mpsbench and the example
  plugin installed by the workflow's own install step, the plugin's tests with the conformance
  kit, the smoke tier of the diffusion case on the example solver, and the comparison against
  the baseline committed in examples/plugin/mpsbench-baseline/.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import venv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml
from junitparser import JUnitXml

from mpsbench import cli
from mpsbench.results.compare_json import SCHEMA, comparison_from_json
from tests.fake_cases import ToyDiffusion, only_cases

ROOT = Path(__file__).resolve().parents[1]
GITHUB = ROOT / "examples" / "ci" / "github-actions.yml"
GITLAB = ROOT / "examples" / "ci" / "gitlab-ci.yml"
PLUGIN = ROOT / "examples" / "plugin"
BASH = ["bash", "--noprofile", "--norc", "-eo", "pipefail"]

TOY_MODULE = '''
import os

from tests.fake_cases import ToyDiffusion

CASE = ToyDiffusion()
CASE.fail_check = os.environ.get("TOY_FAIL_CHECK") == "1"
'''


def load(path: Path) -> dict[Any, Any]:
    """A YAML document's mapping (keys not only strings: YAML 1.1 reads a bare ``on`` as True)."""
    doc = yaml.safe_load(path.read_text())
    assert isinstance(doc, dict), path
    return doc


# --------------------------------------------------------------------------- a GitHub runner


@dataclass
class StepRun:
    name: str
    ran: bool
    code: int = 0
    output: str = ""


_TERM = re.compile(r"^(?:(?P<fn>!cancelled\(\)|always\(\)|success\(\))|"
                   r"steps\.(?P<id>[\w-]+)\.(?:outcome|conclusion) == '(?P<value>\w+)')$")


def condition(expr: str | None, failed: bool, outcomes: dict[str, str]) -> bool:
    """An ``if:`` of the forms the example uses: terms joined by ``&&``; no ``if`` = success()."""
    if expr is None:
        return not failed
    text = expr.strip()
    if text.startswith("${{") and text.endswith("}}"):
        text = text[3:-2].strip()
    result = True
    for term in (t.strip() for t in text.split("&&")):
        m = _TERM.match(term)
        assert m, f"the test's runner does not understand the condition {term!r} of {expr!r}"
        if m["fn"] == "success()":
            result &= not failed
        elif m["fn"]:
            result &= True  # the run is never cancelled here
        else:
            result &= outcomes.get(m["id"], "skipped") == m["value"]
    return result


def run_workflow(doc: dict[str, Any], cwd: Path, env: dict[str, str], *,
                 stand_in: dict[str, str] | None = None,
                 only: tuple[str, ...] | None = None) -> list[StepRun]:
    """Run the job's steps in order.  ``stand_in``: step id -> outcome for steps not run (the
    install step when this environment stands in for it); ``only``: run just these steps."""
    (job,) = doc["jobs"].values()
    environ = {**{k: str(v) for k, v in doc.get("env", {}).items()}, **env}
    assert doc["defaults"]["run"]["shell"] == "bash"
    results, outcomes, failed = [], dict(stand_in or {}), False
    for step in job["steps"]:
        name = step.get("name") or step.get("uses", "?")
        if "uses" in step or step.get("id") in (stand_in or {}) or \
                (only is not None and name not in only):
            results.append(StepRun(name, False))
            continue
        if not condition(step.get("if"), failed, outcomes):
            results.append(StepRun(name, False))
            if step.get("id"):
                outcomes[step["id"]] = "skipped"
            continue
        script = step["run"]
        assert "${{" not in script, f"step {name!r}: keep ${{{{ }}}} out of run: blocks"
        proc = subprocess.run([*BASH, "-c", script], cwd=cwd, capture_output=True, text=True,
                              env={**environ, **{k: str(v) for k, v in
                                                 step.get("env", {}).items()}},
                              timeout=1800)
        results.append(StepRun(name, True, proc.returncode, proc.stdout + proc.stderr))
        failed |= proc.returncode != 0
        if step.get("id"):
            outcomes[step["id"]] = "success" if proc.returncode == 0 else "failure"
    return results


def by_name(runs: list[StepRun]) -> dict[str, StepRun]:
    return {r.name: r for r in runs}


def upload_paths(doc: dict[str, Any], env: dict[str, str]) -> list[str]:
    """The paths of the upload-artifact steps, ``${{ env.X }}`` resolved."""
    (job,) = doc["jobs"].values()
    merged = {**{k: str(v) for k, v in doc.get("env", {}).items()}, **env}
    paths = []
    for step in job["steps"]:
        if str(step.get("uses", "")).startswith("actions/upload-artifact@"):
            assert step.get("if") == "${{ !cancelled() }}", "upload the report even on failure"
            paths.append(re.sub(r"\$\{\{\s*env\.(\w+)\s*\}\}", lambda m: merged[m[1]],
                                step["with"]["path"]))
    return paths


# --------------------------------------------------------------------------- shared set-up


def tiny_plugin(folder: Path) -> Path:
    """A plugin declaring tests.fake_cases' ToyDiffusion as the case ``toy-diffusion``, laid out
    as pip installs one (a module and a .dist-info with entry_points.txt) on a PYTHONPATH."""
    folder.mkdir(parents=True)
    (folder / "mpsbench_ci_toy.py").write_text(TOY_MODULE)
    info = folder / "mpsbench_ci_toy-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: mpsbench-ci-toy\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[mpsbench.cases]\ntoy-diffusion = mpsbench_ci_toy:CASE\n")
    return folder


def local_env(tmp_path: Path) -> dict[str, str]:
    """This checkout's environment (its python and mpsbench first on PATH), the tiny plugin."""
    site = tiny_plugin(tmp_path / "site")
    bindir = str(Path(sys.executable).parent)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("GITHUB_", "PYTEST_"))}
    return {**env, "PATH": f"{bindir}{os.pathsep}{env.get('PATH', '')}",
            "PYTHONPATH": f"{site}{os.pathsep}{ROOT}", "PYTEST_ADDOPTS": "-p no:cacheprovider",
            "SOLVER": "reference", "CASE": "toy-diffusion", "SETTINGS": "--set steps=2"}


def make_baseline(repo: Path) -> Path:
    """The baseline a solver author commits: results.json of a trusted run of the same command."""
    out = repo / "first-run"
    with only_cases(ToyDiffusion()):
        assert cli.main(["validate", "toy-diffusion", "--tier", "smoke", "--set", "steps=2",
                         "--out", str(out)]) == 0
    dest = repo / "mpsbench-baseline" / "results.json"
    dest.parent.mkdir(parents=True)
    shutil.copy(out / "results.json", dest)
    shutil.rmtree(out)
    return dest


def check_outputs(out: Path, suites: set[str]) -> dict[str, Any]:
    """The report folder after a green run: JUnit files that parse, compare.json that loads."""
    pytest_xml = JUnitXml.fromfile(str(out / "pytest.xml"))
    kit = [c for s in pytest_xml for c in s if c.classname.startswith("mpsbench-conformance[")]
    assert kit and all(c.is_passed or c.is_skipped for c in kit)
    smoke = JUnitXml.fromfile(str(out / "smoke.xml"))
    assert {s.name for s in smoke} == suites
    assert all(s.failures == 0 and s.errors == 0 and s.tests >= 3 for s in smoke)
    doc = json.loads((out / "compare.json").read_text())
    assert doc["schema"] == SCHEMA and doc["verdict"] == "ok", doc
    rebuilt = comparison_from_json(doc)
    assert {k: rebuilt.count(k) for k in doc["counts"]} == doc["counts"]
    assert (out / "smoke" / "compare.md").is_file() and (out / "smoke" / "index.html").is_file()
    return doc


# --------------------------------------------------------------------------- the tests


def test_github_workflow_steps_run_locally(tmp_path: Path) -> None:
    doc = load(GITHUB)
    triggers = doc.get("on", doc.get(True))  # YAML 1.1: on = True
    assert triggers is not None and set(triggers) == {"push", "pull_request"}
    (job,) = doc["jobs"].values()
    uses = [s["uses"].split("@")[0] for s in job["steps"] if "uses" in s]
    assert uses == ["actions/checkout", "actions/setup-python", "actions/upload-artifact"]
    install = next(s for s in job["steps"] if s.get("id") == "install")
    assert 'pip install "$MPSBENCH" "$PLUGIN"' in install["run"]

    repo = tmp_path / "repo"
    repo.mkdir()
    make_baseline(repo)
    summary = tmp_path / "step-summary.md"
    env = {**local_env(tmp_path), "GITHUB_STEP_SUMMARY": str(summary)}
    runs = run_workflow(doc, repo, env, stand_in={"install": "success"})
    ran = [r for r in runs if r.ran]
    assert [r.name for r in ran] == ["Tests and conformance kit", "Smoke tier",
                                     "Compare against the baseline"]
    for r in ran:
        assert r.code == 0, f"{r.name}:\n{r.output[-3000:]}"
    out = repo / doc["env"]["OUT"]
    cmp = check_outputs(out, {"toy-diffusion[reference]"})
    assert cmp["matched"] == 2 and cmp["counts"]["regression"] == 0
    text = summary.read_text()
    assert "## mpsbench validate (toy-diffusion, tier smoke): PASS" in text
    assert "## mpsbench compare: no regression" in text
    assert all((repo / p).is_dir() for p in upload_paths(doc, env))

    # a failing check fails the smoke step (exit 1, a JUnit failure) and the steps after it
    # still run, so the comparison shows the numbers
    shutil.rmtree(out)
    runs = run_workflow(doc, repo, {**env, "TOY_FAIL_CHECK": "1"}, stand_in={"install": "success"},
                        only=("Smoke tier",))
    smoke = by_name(runs)["Smoke tier"]
    assert smoke.code == 1 and "FAIL toy-diffusion" in smoke.output
    assert JUnitXml.fromfile(str(out / "smoke.xml")).failures == 1
    later = [s for s in job["steps"] if s.get("name") in ("Compare against the baseline",
                                                           "Upload the report")]
    assert len(later) == 2
    assert all(condition(s["if"], failed=True, outcomes={"install": "success"}) for s in later)
    assert not condition(later[0]["if"], failed=True, outcomes={"install": "failure"})

    # no baseline yet: the comparison is skipped with a warning, not an error
    runs = run_workflow(doc, repo, {**env, "BASELINE": "nowhere/results.json"},
                        stand_in={"install": "success"}, only=("Compare against the baseline",))
    step = by_name(runs)["Compare against the baseline"]
    assert step.code == 0 and "::warning::no baseline at nowhere/results.json" in step.output


def gitlab_commands(doc: dict[str, Any]) -> list[str]:
    """The job's commands without GitLab's bookkeeping (status=..., '|| status=1', exit)."""
    lines = []
    for line in doc["mpsbench"]["script"]:
        line = re.sub(r"\s*\|\|\s*status=1", "", line).strip()
        if not re.fullmatch(r"status=0|exit \"\$status\"", line):
            lines.append(line)
    return lines


def test_gitlab_job_runs_the_workflows_commands() -> None:
    """The GitLab job is the workflow's steps in one script: same variables, same commands."""
    gitlab, github = load(GITLAB), load(GITHUB)
    job = gitlab["mpsbench"]
    variables = {k: str(v) for k, v in job["variables"].items()}
    assert variables == {k: str(v) for k, v in github["env"].items()}
    out_dir = variables["OUT"]
    assert job["artifacts"]["when"] == "always" and job["artifacts"]["paths"] == [f"{out_dir}/"]
    assert job["artifacts"]["reports"]["junit"] == [f"{out_dir}/pytest.xml",
                                                     f"{out_dir}/smoke.xml"]
    (steps,) = github["jobs"].values()
    first, *runs = [" ".join(s["run"].replace("\\\n", " ").split()) for s in steps["steps"]
                    if "run" in s]
    install = 'python -m pip install "$MPSBENCH" "$PLUGIN"'
    assert install in first
    got = [" ".join(line.split()) for line in gitlab_commands(gitlab)]
    assert got[0] == install
    assert got[1:] == [w.replace("::warning::", "") for w in runs]


@pytest.mark.slow
def test_gitlab_job_script_runs_locally(tmp_path: Path) -> None:
    """The job's script (less the install line, which this checkout stands in for) in one shell,
    as GitLab runs it: green, then with a failing check (every line runs, the job fails)."""
    doc = load(GITLAB)
    job = doc["mpsbench"]
    install, *script = job["script"]
    assert install == 'python -m pip install "$MPSBENCH" "$PLUGIN"'
    repo = tmp_path / "repo"
    repo.mkdir()
    make_baseline(repo)
    env = {**{k: str(v) for k, v in job["variables"].items()}, **local_env(tmp_path)}
    out_dir = repo / env["OUT"]
    proc = subprocess.run([*BASH, "-c", "\n".join(script)], cwd=repo, env=env,
                          capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    check_outputs(out_dir, {"toy-diffusion[reference]"})

    env["TOY_FAIL_CHECK"] = "1"
    shutil.rmtree(out_dir)
    proc = subprocess.run([*BASH, "-c", "\n".join(script)], cwd=repo, env=env,
                          capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 1, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert json.loads((out_dir / "compare.json").read_text())["verdict"] == "ok"


@pytest.mark.slow
def test_github_workflow_for_real_in_a_fresh_venv(tmp_path: Path) -> None:
    """Every step of the workflow, the install step included, in a new virtual environment."""
    doc = load(GITHUB)
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    repo = tmp_path / "repo"  # the plugin's repository, as actions/checkout leaves it
    shutil.copytree(PLUGIN, repo, ignore=shutil.ignore_patterns(
        "build", "*.egg-info", "__pycache__", ".pytest_cache"))
    summary = tmp_path / "step-summary.md"
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV") and not k.startswith(("GITHUB_", "PYTEST_"))}
    env.update(PATH=f"{env_dir / 'bin'}{os.pathsep}{env['PATH']}", MPSBENCH=f"{ROOT}[fast]",
               GITHUB_STEP_SUMMARY=str(summary))
    runs = run_workflow(doc, repo, env)
    for r in runs:
        if r.ran:
            assert r.code == 0, f"{r.name}:\n{r.output[-4000:]}"
    assert [r.name for r in runs if r.ran] == [
        "Install mpsbench and the plugin", "Tests and conformance kit", "Smoke tier",
        "Compare against the baseline"]
    install = by_name(runs)["Install mpsbench and the plugin"].output
    assert "example" in install  # 'mpsbench solvers' lists the plugin's solver
    out = repo / doc["env"]["OUT"]
    cmp = check_outputs(out, {"diffusion[example]"})
    assert cmp["matched"] == 2 and cmp["baseline"]["path"] == doc["env"]["BASELINE"]
    tests = JUnitXml.fromfile(str(out / "pytest.xml"))
    names = {c.name for s in tests for c in s}
    assert "test_diffusion_case" in names  # the plugin's own tests ran too
    assert "## mpsbench compare: no regression" in summary.read_text()
    assert all((repo / p).is_dir() for p in upload_paths(doc, env))
