"""Write one documentation page per registered environment id (``docs/environments/<name>.md``), Gymnasium style.

    python scripts/docs_env_pages.py [--out docs/environments] [--check]

Each page is built from the code, so that it cannot drift from it:

* the spaces, ``max_episode_steps`` and the reward terms of ``info`` come from an environment made with
  ``gymnasium.make`` and reset once;
* the sections (Description, Action Space, Observation Space, Rewards, Costs, Starting State, Episode End,
  Arguments, Version History, ...) are the ``## <section>`` blocks of the class docstrings along the class's MRO,
  the most derived class's block winning (so a v1 page shows the v1 rewards and version history, and v0's
  description);
* the observation layout is the table of :mod:`uvdms_gym.envs.base`'s docstring;
* the keyword table lists every keyword argument of the class and its bases with its effective default
  (the v1 reward weights included) and the range from :data:`RANGES` (a keyword missing there is an error).

``--check`` writes nothing and exits with status 1 when a committed page differs from what would be written
(``tests/docs/test_docs_site.py`` runs the same comparison).
"""

from __future__ import annotations

import argparse
import inspect
import re
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym

import uvdms_gym
from uvdms_gym.envs import base

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "docs" / "environments"

RANGES: dict[str, str] = {
    "action_mode": '`"velocity"`, `"torque"` or `"thrusters"` (8 thruster commands, 12 joint torques)',
    "realism": "`0` (the oracle), `1`, `2`, `3`, or a mapping `{level: L, <knob>: value}` ([realism](../realism.md))",
    "control_dt": "> 0 s, a whole multiple of `physics_dt`",
    "physics_dt": "> 0 s",
    "hydro_randomization": "[0, 1)",
    "current": '`None`, a NED vector (m/s, norm <= 2) or `"random"`',
    "terminate_on_contact": "bool",
    "track_weight": ">= 0",
    "orientation_weight": ">= 0",
    "effort_weight": ">= 0",
    "proximity_weight": ">= 0",
    "contact_weight": ">= 0",
    "max_tracking_error": "> 0 m",
    "render_mode": '`None`, `"rgb_array"` or `"human"` (needs a display)',
    "render_width": "pixels, > 0",
    "render_height": "pixels, > 0",
    "params": "`UVDMSParams` or `None` (the paper's system)",
    "case": '`1`, `2`, `"random"` or `"mix"`',
    "left_center": "NED m (3 floats), overrides the case",
    "right_center": "NED m (3 floats), overrides the case",
    "radius": "> 0 m, reachable (checked)",
    "period": "> 0 s",
    "goal": '`"paper"` or `"random"`',
    "start_pose": "NED m + ZYX Euler degrees (6 floats)",
    "goal_pose": "NED m + ZYX Euler degrees (6 floats), reachable (checked)",
    "move_time": "> 0 s",
    "track_scale": "> 0 m",
    "orientation_scale": "> 0 rad",
    "precision_weight": ">= 0 (0: term off)",
    "precision_scale": "> 0 m",
    "obstacles": '`"random"` or a list of obstacle specifications ([OBSTACLES](../OBSTACLES.md))',
    "n_observed_obstacles": ">= 0 observation slots",
    "grasp": '`"rigid"` (the object welded to both hands), `"friction"` (held by friction, two grip commands more), '
    'or a mapping of the friction knobs `{"mu": 0.4, "crush_force": 120, ...}` (`mu`, `torsion_radius`: one value '
    "or `[left, right]`; `grip_max`, `crush_force`, `drop_slip`, `grip_initial`: `FrictionGraspConfig`)",
}
"""The admissible values of every environment keyword (the constructors check them)."""
SECTION_ORDER = (
    "Description",
    "Action Space",
    "Observation Space",
    "Rewards",
    "Costs",
    "Info",
    "Starting State",
    "Episode End",
    "Arguments",
    "Version History",
)
ROLE = re.compile(r":(?:mod|class|func|meth|data|attr|exc):`~?([\w.]+)`")


def rst_to_markdown(text: str) -> str:
    """Inline reStructuredText of the docstrings as Markdown: ``x`` -> `x`, roles -> their last name in code."""
    text = ROLE.sub(lambda m: f"`{m.group(1).rsplit('.', 1)[-1]}`", text)
    return text.replace("``", "`")


def docstring_sections(cls: type) -> tuple[str, dict[str, str]]:
    """The summary line of ``cls`` and its ``## <section>`` blocks merged along the MRO (derived classes win)."""
    sections: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        doc = inspect.cleandoc(klass.__dict__.get("__doc__") or "")
        for name, body in re.findall(r"^## (.+?)\n(.*?)(?=^## |\Z)", doc, flags=re.M | re.S):
            sections[name.strip()] = rst_to_markdown(body.strip())
    summary = inspect.cleandoc(cls.__doc__ or "").split("\n\n", 1)[0].replace("\n", " ")
    return rst_to_markdown(summary), sections


def keyword_defaults(cls: type) -> dict[str, Any]:
    """Every keyword argument of ``cls`` and its bases with its effective default."""
    defaults: dict[str, Any] = {}
    for klass in cls.__mro__:
        init = klass.__dict__.get("__init__")
        if init is None or klass.__module__.startswith("gymnasium"):
            continue
        for name, param in inspect.signature(init).parameters.items():
            if param.kind is param.KEYWORD_ONLY or (param.kind is param.POSITIONAL_OR_KEYWORD and name != "self"):
                defaults.setdefault(name, param.default)
    overrides = getattr(cls, "default_weights", None)
    if overrides:
        defaults.update(overrides)
    return defaults


def _observation_table() -> str:
    """The observation layout of :mod:`uvdms_gym.envs.base` as a Markdown table."""
    doc = base.__doc__ or ""
    block = doc.split("==========  ====", 3)[2].split("\n", 1)[1].rsplit("==========", 1)[0]
    rows: list[list[str]] = []
    for line in block.splitlines():
        if not line.strip() or line.startswith("======"):
            continue
        if line[:10].strip():
            rows.append([line[:10].strip(), line[12:16].strip(), line[18:].strip()])
        else:
            rows[-1][2] += " " + line.strip()
    out = ["| slice | size | content |", "|---|--:|---|"]
    out += [f"| `{s}` | {n} | {rst_to_markdown(c)} |" for s, n, c in rows]
    return "\n".join(out)


def _keyword_table(cls: type) -> str:
    out = ["| keyword | default | range |", "|---|---|---|"]
    for name, default in keyword_defaults(cls).items():
        if name not in RANGES:
            raise KeyError(f"{cls.__name__}: keyword {name!r} has no range in RANGES (scripts/docs_env_pages.py)")
        out.append(f"| `{name}` | `{default!r}` | {RANGES[name]} |")
    return "\n".join(out)


def page(env_id: str) -> str:
    """The Markdown page of ``env_id``."""
    spec = gym.spec(env_id)
    env = gym.make(env_id)
    try:
        _, info = env.reset(seed=0)
        cls = type(env.unwrapped)
        obs_space, act_space = env.observation_space, env.action_space
        reward_terms = sorted(k for k in info if k.startswith("reward_"))
        cost_terms = sorted(k for k in info if k.startswith("cost_"))
    finally:
        env.close()
    summary, sections = docstring_sections(cls)
    lines = [
        f"# `{env_id}`",
        "",
        summary,
        "",
        "| | |",
        "|---|---|",
        f'| Make | `gymnasium.make("{env_id}")` (after `import uvdms_gym`) |',
        f"| Class | `{cls.__module__}.{cls.__name__}` |",
        f"| Action space | `Box({act_space.low.min():g}, {act_space.high.max():g}, {act_space.shape}, "
        f"{act_space.dtype})` |",
        f"| Observation space | `Box({obs_space.low.min():g}, {obs_space.high.max():g}, {obs_space.shape}, "
        f"{obs_space.dtype})` |",
        f"| `max_episode_steps` | {spec.max_episode_steps} |",
        f"| Reward terms in `info` | {', '.join(f'`{k}`' for k in reward_terms)} |",
        f"| Cost terms in `info` | {', '.join(f'`{k}`' for k in cost_terms)} (summed in `cost`) |",
        "",
    ]
    for name in SECTION_ORDER:
        if name in sections:
            lines += [f"## {name}", "", sections[name], ""]
            if name == "Observation Space":
                lines += ["The first 80 values:", "", _observation_table(), ""]
            if name == "Arguments":
                lines += [_keyword_table(cls), ""]
    extra = [n for n in sections if n not in SECTION_ORDER]
    for name in extra:
        lines += [f"## {name}", "", sections[name], ""]
    lines += [
        "---",
        "Generated from the code by `python scripts/docs_env_pages.py`; edit the class docstrings, not this page.",
        "",
    ]
    return "\n".join(lines)


def page_name(env_id: str) -> str:
    """File name of ``env_id``'s page: ``uvdms/CircleTrack-v1`` -> ``CircleTrack-v1.md``."""
    return env_id.split("/", 1)[1] + ".md"


def main(argv: list[str] | None = None) -> int:
    """Write (or with ``--check`` compare) every environment's page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--check", action="store_true", help="compare with the committed pages, write nothing")
    args = parser.parse_args(argv)
    stale = []
    for env_id in uvdms_gym.ENV_IDS:
        path = args.out / page_name(env_id)
        text = page(env_id)
        if args.check:
            if not path.exists() or path.read_text(encoding="utf-8") != text:
                stale.append(str(path))
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
    if stale:
        sys.stderr.write(f"stale environment pages (run scripts/docs_env_pages.py): {stale}\n")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
