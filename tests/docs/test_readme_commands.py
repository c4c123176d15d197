"""Every ``uvdms`` command in the ```bash blocks of README.md and of the documentation site's pages (``docs/``, but
the generated ``docs/leaderboard/``) runs, at a tiny budget, through the real console script.

:data:`SHRUNK` lists, per README command, the command actually run: the same arguments with a smaller budget
(``--episodes 1``, ``--total-timesteps`` of a few hundred, ``max_episode_steps`` of a few dozen, ``--quick``,
``--max-episode-steps`` for the leaderboard, cheaper training hyper-parameters), placeholders such as
``path/to/agent_export`` replaced by a real agent, and ``--no-progress``.
:func:`test_the_table_covers_the_readme_and_the_docs` fails when the README or a docs page has a ``uvdms`` command
the table does not list (or the table one they all lost), so they cannot drift apart;
:func:`test_shrunk_commands_keep_the_readme_arguments` checks that each shrunk command still contains every
documented argument except the budget values.

The commands run in a temporary working directory (``trained_agents`` links to the repository's, so that
relative paths and the trusted-agents rule work as in a checkout), in :data:`CHAINS`: commands that depend on
each other (train, resume, export, evaluate the export) run in order in one directory; independent chains are
separate tests so that ``pytest -n 2`` runs them side by side.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
README = REPO / "README.md"
DOCS = REPO / "docs"


def documented_text() -> str:
    """README.md and every hand-written page of the documentation site, concatenated."""
    pages = sorted(p for p in DOCS.rglob("*.md") if not p.is_relative_to(DOCS / "leaderboard"))
    return "\n".join(page.read_text(encoding="utf-8") for page in [README, *pages])


UVDMS = Path(sys.executable).parent / "uvdms"

BUDGET_OPTIONS = ("--episodes", "--total-timesteps")
"""Options whose README value may be replaced by a smaller one."""
PLACEHOLDERS = {"path/to/agent_export": "exported/sac_case1"}
"""README placeholders and the agents the tests use for them (made earlier in the same chain)."""
TINY_SAC = "learning_starts=100 eval_freq=100 n_eval_episodes=1 checkpoint_freq=200"
"""SAC at a tiny budget: learn after 100 steps, evaluate (and keep a best model) every 100."""
TINY_PPO = "n_steps=64 batch_size=64 n_epochs=2 eval_freq=128 n_eval_episodes=1 checkpoint_freq=128"
"""PPO at a tiny budget: rollouts of 64 steps per env."""


@dataclass(frozen=True)
class Shrunk:
    """How one README command is run.

    Attributes:
        chain: The test it runs in (:data:`CHAINS`).
        run: The command run (``uvdms ...``).
        creates: Files or folders it must create (relative to the working directory).
        stdout_json: Its stdout is a JSON document.
        contains: ``(file, text)`` pairs: the file (``-`` for stdout) must contain the text.
    """

    chain: str
    run: str
    creates: tuple[str, ...] = ()
    stdout_json: bool = False
    contains: tuple[tuple[str, str], ...] = ()


SHRUNK: dict[str, Shrunk] = {
    # quick start and leaderboard section (the same command twice)
    "uvdms leaderboard --quick": Shrunk(
        "leaderboard",
        "uvdms leaderboard --quick --episodes 1 --max-episode-steps 20 --no-progress",
        creates=(
            "leaderboard_out/leaderboard.md",
            "leaderboard_out/leaderboard.csv",
            "leaderboard_out/index.html",
            "leaderboard_out/plots",
        ),
        contains=(
            ("-", "### Velocity track"),
            ("leaderboard_out/leaderboard.md", "1-minute load average"),
            ("leaderboard_out/leaderboard.csv", "timing_episodes_overloaded"),
        ),
    ),
    "uvdms leaderboard --out docs/leaderboard": Shrunk(
        "leaderboard",
        "uvdms leaderboard --out docs/leaderboard --episodes 1 --max-episode-steps 20 --no-progress "
        "--cache-dir leaderboard_out/cache",
        creates=("docs/leaderboard/leaderboard.md", "docs/leaderboard/entries/campc.json"),
    ),
    "uvdms leaderboard --out docs/leaderboard --reuse docs/leaderboard": Shrunk(
        "leaderboard",
        "uvdms leaderboard --out docs/leaderboard --reuse docs/leaderboard --episodes 1 --max-episode-steps 20 "
        "--no-progress --cache-dir leaderboard_out/reuse_cache",
        creates=("docs/leaderboard/leaderboard.md", "docs/leaderboard/entries/campc.json"),
        contains=(("docs/leaderboard/leaderboard.md", "campc"),),
    ),
    "uvdms leaderboard --entries baselines agents out/my_export": Shrunk(
        "leaderboard",
        "uvdms leaderboard --entries baselines agents out/my_export --quick --episodes 1 --max-episode-steps 20 "
        "--no-progress",
        creates=("leaderboard_out/entries/my_export.json",),
    ),
    "uvdms leaderboard --quick --entries baselines agents out/my_export": Shrunk(
        "leaderboard",
        "uvdms leaderboard --quick --entries baselines agents out/my_export --episodes 1 --max-episode-steps 20 "
        "--no-progress",
        creates=("leaderboard_out/entries/my_export.json",),
    ),
    "uvdms export-agent trained_agents/ppo-circle-case1-v0 out/my_export": Shrunk(
        "leaderboard",
        "uvdms export-agent trained_agents/ppo-circle-case1-v0 out/my_export",
        creates=("out/my_export/agent.json", "out/my_export/policy.pt"),
    ),
    # docs/seeds.md: development on validation draws
    "uvdms evaluate --controller campc --env uvdms/CircleTrack-v0 --env-kwargs case=random --episodes 2 "
    "--out out/val.json": Shrunk(
        "evaluate",
        "uvdms evaluate --controller campc --env uvdms/CircleTrack-v0 --env-kwargs case=random max_episode_steps=20 "
        "--episodes 2 --out out/val.json --no-progress",
        creates=("out/val.json",),
        stdout_json=True,
        contains=(("out/val.json", '"split": "validation"'),),
    ),
    "uvdms leaderboard --split validation --tasks circle-random --entries campc hold --out out/lb-validation": Shrunk(
        "leaderboard",
        "uvdms leaderboard --split validation --tasks circle-random --entries campc hold --out out/lb-validation "
        "--episodes 2 --max-episode-steps 20 --no-progress",
        creates=("out/lb-validation/leaderboard.csv",),
        contains=(("out/lb-validation/leaderboard.md", "the `validation` split"),),
    ),
    # docs/OBSTACLES.md: a scripted obstacle through --env-kwargs
    "uvdms evaluate --controller campc --env uvdms/TransportObstacles-v1 --episodes 1 --env-kwargs "
    "'obstacles=[{shape: sphere, radius: 0.08, position: [3.5, 1.5, 29.0], velocity: [-0.05, 0.02, 0.01]}]'": Shrunk(
        "evaluate",
        "uvdms evaluate --controller campc --env uvdms/TransportObstacles-v1 --episodes 1 --env-kwargs "
        "'obstacles=[{shape: sphere, radius: 0.08, position: [3.5, 1.5, 29.0], velocity: [-0.05, 0.02, 0.01]}]' "
        "max_episode_steps=20 --no-progress",
        stdout_json=True,
    ),
    # reference controller section
    "uvdms evaluate --controller campc --env uvdms/CircleTrack-v0 --env-kwargs case=2 --episodes 5 "
    "--out out/campc.json": (
        Shrunk(
            "evaluate",
            "uvdms evaluate --controller campc --env uvdms/CircleTrack-v0 --env-kwargs case=2 max_episode_steps=20 "
            "--episodes 1 --out out/campc.json --no-progress",
            creates=("out/campc.json",),
            stdout_json=True,
            contains=(("out/campc.json", '"load_1min_start"'), ("-", '"episodes": 1')),
        )
    ),
    "uvdms evaluate --controller campc-nndi --env uvdms/Transport-v0 --env-kwargs hydro_randomization=0.3 "
    "--episodes 5": Shrunk(
        "evaluate",
        "uvdms evaluate --controller campc-nndi --env uvdms/Transport-v0 --env-kwargs hydro_randomization=0.3 "
        "max_episode_steps=20 --episodes 1 --no-progress",
        stdout_json=True,
    ),
    "uvdms evaluate --controller path/to/agent_export --env uvdms/CircleTrack-v0 --episodes 5": Shrunk(
        "train",
        "uvdms evaluate --controller exported/sac_case1 --env uvdms/CircleTrack-v0 --env-kwargs max_episode_steps=20 "
        "--episodes 1 --no-progress",
        stdout_json=True,
    ),
    "uvdms reproduce --out docs/figures --check": Shrunk(
        "reproduce",
        "uvdms reproduce --out docs/figures --check --quick",
        creates=("docs/figures/summary.md", "docs/figures/results.json", "docs/figures/fig09_min_distances.png"),
    ),
    "uvdms bench mpc --json": Shrunk(
        "bench", "uvdms bench mpc --json --quick", stdout_json=True, contains=(("-", '"load_1min_end"'),)
    ),
    # train section
    "uvdms train --algo sac --env uvdms/CircleTrack-v0 --env-kwargs case=1 --seed 0 --total-timesteps 60000": Shrunk(
        "train",
        "uvdms train --algo sac --env uvdms/CircleTrack-v0 --env-kwargs case=1 max_episode_steps=20 --seed 0 "
        f"--total-timesteps 300 --hyperparams {TINY_SAC} --no-progress",
        creates=("runs/uvdms_CircleTrack-v0/sac_0/final_model.zip", "runs/uvdms_CircleTrack-v0/sac_0/best_model.zip"),
    ),
    "uvdms train --algo ppo --env uvdms/Transport-v0 --env-kwargs goal=paper --hyperparams learning_rate=1.0e-4": (
        Shrunk(
            "train",
            "uvdms train --algo ppo --env uvdms/Transport-v0 --env-kwargs goal=paper max_episode_steps=20 "
            f"--hyperparams learning_rate=1.0e-4 {TINY_PPO} --total-timesteps 256 --no-progress",
            creates=("runs/uvdms_Transport-v0/ppo_0/final_model.zip",),
        )
    ),
    "uvdms train --algo ppo_lagrangian --env uvdms/CircleTrack-v1 --hyperparams cost_limit=5.0 --seed 0": Shrunk(
        "train",
        "uvdms train --algo ppo_lagrangian --env uvdms/CircleTrack-v1 --env-kwargs max_episode_steps=20 "
        f"--hyperparams cost_limit=5.0 {TINY_PPO} --seed 0 --total-timesteps 256 --no-progress",
        creates=(
            "runs/uvdms_CircleTrack-v1/ppo_lagrangian_0/final_model.zip",
            "runs/uvdms_CircleTrack-v1/ppo_lagrangian_0/lagrangian.csv",
        ),
        contains=(("runs/uvdms_CircleTrack-v1/ppo_lagrangian_0/lagrangian.csv", "cost_limit,lambda"),),
    ),
    "uvdms train --resume runs/uvdms_CircleTrack-v0/sac_0 --total-timesteps 20000": Shrunk(
        "train",
        "uvdms train --resume runs/uvdms_CircleTrack-v0/sac_0 --total-timesteps 200 --no-progress",
        creates=("runs/uvdms_CircleTrack-v0/sac_0/logs/seg1",),
    ),
    "uvdms export-agent runs/uvdms_CircleTrack-v0/sac_0 exported/sac_case1 --which best --trust": Shrunk(
        "train",
        "uvdms export-agent runs/uvdms_CircleTrack-v0/sac_0 exported/sac_case1 --which best --trust",
        creates=("exported/sac_case1/agent.json", "exported/sac_case1/policy.pt"),
    ),
    "uvdms evaluate --controller trained_agents/ppo-circle-case1-v0 --env uvdms/CircleTrack-v0 --env-kwargs case=1 "
    "--episodes 10 --split validation --out out/eval.json": Shrunk(
        "evaluate",
        "uvdms evaluate --controller trained_agents/ppo-circle-case1-v0 --env uvdms/CircleTrack-v0 --env-kwargs case=1 "
        "max_episode_steps=20 --episodes 1 --split validation --out out/eval.json --no-progress",
        creates=("out/eval.json",),
        stdout_json=True,
    ),
    # residual agents
    "uvdms train --algo sac --env uvdms/CircleTrack-v0 --env-kwargs case=1 --seed 1 --residual mpc "
    "--residual-scale 0.2 --total-timesteps 60000": Shrunk(
        "residual",
        "uvdms train --algo sac --env uvdms/CircleTrack-v0 --env-kwargs case=1 max_episode_steps=20 --seed 1 "
        f"--residual mpc --residual-scale 0.2 --total-timesteps 200 --hyperparams {TINY_SAC} --no-progress",
        creates=("runs/uvdms_CircleTrack-v0/sac_1/final_model.zip",),
        contains=(("runs/uvdms_CircleTrack-v0/sac_1/config.yml", "residual_base: mpc"),),
    ),
    "uvdms export-agent runs/uvdms_CircleTrack-v0/sac_1 exported/residual-mpc-sac --trust": Shrunk(
        "residual",
        "uvdms export-agent runs/uvdms_CircleTrack-v0/sac_1 exported/residual-mpc-sac --trust",
        creates=("exported/residual-mpc-sac/agent.json",),
        contains=(("exported/residual-mpc-sac/agent.json", '"residual_base": "mpc"'),),
    ),
    "uvdms evaluate --controller exported/residual-mpc-sac --env uvdms/CircleTrack-v0 --env-kwargs case=1 "
    "--episodes 5": Shrunk(
        "residual",
        "uvdms evaluate --controller exported/residual-mpc-sac --env uvdms/CircleTrack-v0 --env-kwargs case=1 "
        "max_episode_steps=20 --episodes 1 --no-progress",
        stdout_json=True,
    ),
    # imitation: DAgger on a residual over mpc, CAMPC (2 cm margin) the teacher
    "uvdms train --algo dagger --env uvdms/CircleTrack-v1 --env-kwargs case=mix hydro_randomization=0.3 "
    "--residual mpc --residual-scale 0.5 --residual-observation clearance --hyperparams teacher=campc "
    "teacher_margin=0.02 --total-timesteps 100000": Shrunk(
        "dagger",
        "uvdms train --algo dagger --env uvdms/CircleTrack-v1 --env-kwargs case=mix hydro_randomization=0.3 "
        "max_episode_steps=20 --residual mpc --residual-scale 0.5 --residual-observation clearance --hyperparams "
        "teacher=campc teacher_margin=0.02 batch_size=32 eval_freq=100 n_eval_episodes=1 checkpoint_freq=0 "
        "--total-timesteps 200 --no-progress",
        creates=("runs/uvdms_CircleTrack-v1/dagger_0/final_model.zip",),
        contains=(("runs/uvdms_CircleTrack-v1/dagger_0/config.yml", "teacher_margin: 0.02"),),
    ),
    # a policy with memory under realism: DAgger from the privileged CAMPC, levels 2 and 3 (docs/training/index.md)
    "uvdms train --algo dagger --env uvdms/CircleTrack-v1 --env-kwargs case=random --residual none --hyperparams "
    "teacher=campc-privileged frame_stack=4 action_history=4 navigation_filter=true "
    "'env_variants=[{realism: 2}, {realism: 3}]'": Shrunk(
        "memory",
        "uvdms train --algo dagger --env uvdms/CircleTrack-v1 --env-kwargs case=random max_episode_steps=20 "
        "--residual none --hyperparams teacher=campc-privileged frame_stack=4 action_history=4 navigation_filter=true "
        "'env_variants=[{realism: 2}, {realism: 3}]' batch_size=32 eval_freq=0 checkpoint_freq=0 "
        "--total-timesteps 60 --no-progress",
        creates=("runs/uvdms_CircleTrack-v1/dagger_0/final_model.zip",),
        contains=(("runs/uvdms_CircleTrack-v1/dagger_0/config.yml", "action_history: 4"),),
    ),
    # a network alone with the obstacle features (docs/training/index.md)
    "uvdms train --algo dagger --env uvdms/TransportObstacles-v1 --env-kwargs obstacles=random current=random "
    "--residual none --hyperparams teacher=campc teacher_margin=0.02 obstacle_features=true evasion_weight=2.0": Shrunk(
        "features",
        "uvdms train --algo dagger --env uvdms/TransportObstacles-v1 --env-kwargs obstacles=random current=random "
        "max_episode_steps=20 --residual none --hyperparams teacher=campc teacher_margin=0.02 obstacle_features=true "
        "evasion_weight=2.0 batch_size=32 eval_freq=0 checkpoint_freq=0 --total-timesteps 40 --no-progress",
        creates=("runs/uvdms_TransportObstacles-v1/dagger_0/final_model.zip",),
        contains=(
            ("runs/uvdms_TransportObstacles-v1/dagger_0/config.yml", "obstacle_features: true"),
            ("runs/uvdms_TransportObstacles-v1/dagger_0/config.yml", "evasion_weight: 2.0"),
        ),
    ),
}
"""README command (normalised: see :func:`readme_commands`) -> how it is run."""

ORDER: tuple[str, ...] = (
    # train: the later commands use the run, the resume and the export of the earlier ones
    "uvdms train --algo sac --env uvdms/CircleTrack-v0 --env-kwargs case=1 --seed 0 --total-timesteps 60000",
    "uvdms train --resume runs/uvdms_CircleTrack-v0/sac_0 --total-timesteps 20000",
    "uvdms export-agent runs/uvdms_CircleTrack-v0/sac_0 exported/sac_case1 --which best --trust",
    "uvdms evaluate --controller path/to/agent_export --env uvdms/CircleTrack-v0 --episodes 5",
    # residual: train, export, evaluate the export
    "uvdms train --algo sac --env uvdms/CircleTrack-v0 --env-kwargs case=1 --seed 1 --residual mpc "
    "--residual-scale 0.2 --total-timesteps 60000",
    "uvdms export-agent runs/uvdms_CircleTrack-v0/sac_1 exported/residual-mpc-sac --trust",
    "uvdms evaluate --controller exported/residual-mpc-sac --env uvdms/CircleTrack-v0 --env-kwargs case=1 --episodes 5",
    # leaderboard: the submission is exported first; the full suite and the submission reuse the quick run's cache
    "uvdms export-agent trained_agents/ppo-circle-case1-v0 out/my_export",
    "uvdms leaderboard --quick",
    "uvdms leaderboard --out docs/leaderboard",
    "uvdms leaderboard --out docs/leaderboard --reuse docs/leaderboard",  # reuses the previous command's output
)
"""Commands that must run before the others of their chain, in this order."""


def readme_commands(text: str) -> list[str]:
    """The ``uvdms`` commands of the ```bash blocks of ``text``, normalised.

    Continuation lines are joined, ``&&``-chains split, comments dropped, ``.venv/bin/uvdms`` written ``uvdms``,
    and each command re-quoted with :func:`shlex.join` (so spacing does not matter). Duplicates are kept once.
    """
    commands: list[str] = []
    for block in re.findall(r"^```bash\n(.*?)^```", text, flags=re.M | re.S):
        for line in block.replace("\\\n", " ").splitlines():
            for part in line.split("&&"):
                tokens = shlex.split(part, comments=True)
                if tokens and tokens[0].endswith("/uvdms"):
                    tokens[0] = "uvdms"
                if tokens and tokens[0] == "uvdms":
                    command = shlex.join(tokens)
                    if command not in commands:
                        commands.append(command)
    return commands


def chains() -> dict[str, list[str]]:
    """README commands per chain, in run order (:data:`ORDER` first, then the table's order)."""
    out: dict[str, list[str]] = {}
    for command in sorted(SHRUNK, key=lambda c: ORDER.index(c) if c in ORDER else len(ORDER)):
        out.setdefault(SHRUNK[command].chain, []).append(command)
    return out


CHAINS = chains()


def test_readme_parser_handles_prefixes_chains_continuations_and_comments():
    text = (
        "intro `uvdms demo` (prose: not a block)\n"
        "```bash\n"
        "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/uvdms leaderboard --quick\n"
        "uvdms evaluate --controller campc \\\n    --episodes 5   # five episodes\n"
        "uvdms  leaderboard   --quick\n"
        "```\n"
        "```python\nuvdms = 1\n```\n"
    )
    assert readme_commands(text) == ["uvdms leaderboard --quick", "uvdms evaluate --controller campc --episodes 5"]


def test_the_table_covers_the_readme_and_the_docs():
    commands = readme_commands(documented_text())
    assert commands, "no uvdms command found in the bash blocks of README.md and docs/"
    assert readme_commands(README.read_text(encoding="utf-8")), "no uvdms command in README.md's bash blocks"
    missing = [c for c in commands if c not in SHRUNK]
    assert not missing, f"README/docs commands without a tiny-budget version in SHRUNK: {missing}"
    stale = [c for c in SHRUNK if c not in commands]
    assert not stale, f"SHRUNK lists commands neither the README nor the docs have: {stale}"
    assert all(c in SHRUNK for c in ORDER)


@pytest.mark.parametrize("command", sorted(SHRUNK))
def test_shrunk_commands_keep_the_readme_arguments(command):
    """The run command holds every README token (placeholders substituted) in order, budget values aside."""
    readme = [PLACEHOLDERS.get(t, t) for t in shlex.split(command)]
    run = shlex.split(SHRUNK[command].run)
    kept = [t for i, t in enumerate(readme) if i == 0 or readme[i - 1] not in BUDGET_OPTIONS]
    position = 0
    for token in kept:
        assert token in run[position:], f"{token!r} of the README command is missing from {SHRUNK[command].run!r}"
        position = run.index(token, position) + 1


def _run(command: str, cwd: Path) -> subprocess.CompletedProcess:
    tokens = shlex.split(command)
    assert tokens[0] == "uvdms"
    environ = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "UVDMS_DEBUG")}
    environ["PYTHONPATH"] = os.pathsep.join([str(REPO), environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return subprocess.run(
        [str(UVDMS), *tokens[1:]], cwd=cwd, env=environ, capture_output=True, text=True, timeout=900, check=False
    )


@pytest.mark.slow
@pytest.mark.parametrize("chain", sorted(CHAINS))
def test_readme_commands_run(chain, tmp_path):
    (tmp_path / "trained_agents").symlink_to(REPO / "trained_agents", target_is_directory=True)
    for readme_command in CHAINS[chain]:
        shrunk = SHRUNK[readme_command]
        proc = _run(shrunk.run, tmp_path)
        assert proc.returncode == 0, f"{shrunk.run}\nexit {proc.returncode}\n{proc.stderr[-3000:]}"
        assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
        for path in shrunk.creates:
            assert (tmp_path / path).exists(), f"{shrunk.run} did not create {path}"
        if shrunk.stdout_json:
            doc = json.loads(proc.stdout)
            assert isinstance(doc, dict) and doc
        for file, text in shrunk.contains:
            content = proc.stdout if file == "-" else (tmp_path / file).read_text(encoding="utf-8")
            assert text in content, f"{shrunk.run}: {text!r} not in {file}"
