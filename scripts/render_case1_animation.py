"""Render the README's animation of circle-tracking Case 1: plain MPC (the arms collide) beside CAMPC (it avoids it).

Both controllers run one episode of ``uvdms/CircleTrack-v0`` with ``case=1`` (seed 0, velocity mode, the paper's
set-up: ``terminate_on_contact=False``, so the plain MPC's run goes on through its contacts as in ``uvdms
reproduce``), through :func:`uvdms_gym.evaluation.run_episode` with ``render_mode="rgb_array"`` frames grabbed by a
wrapper. The frames show the two reference circles (magenta) and the current reference points (cyan) drawn by the
environment (:mod:`uvdms_gym.physics.render`). Every :data:`FRAME_EVERY`-th step is kept and played in real time; the
two panels are cropped around the vehicle, put side by side under their labels, and a panel's border turns red
while its controller's run reports a contact. The GIF (one adaptive palette per frame, :data:`PALETTE_COLOURS`
colours) is written with Pillow and must stay below :data:`MAX_BYTES`.

The labels are checked, not assumed: the script fails if the plain MPC's episode has no contact or CAMPC's has one.

Command line (from the repository root): ``python -m scripts.render_case1_animation [--out PATH] [--every N]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from PIL import Image, ImageDraw, ImageFont

import uvdms_gym  # noqa: F401  (registers the environments)
from leaderboard.suite.registry import make_controller
from uvdms_gym.evaluation import run_episode
from uvdms_gym.utils.provenance import REPO_ROOT

ENV_ID = "uvdms/CircleTrack-v0"
ENV_KWARGS: dict[str, Any] = {"case": 1, "action_mode": "velocity", "terminate_on_contact": False}
SEED = 0
PANELS: tuple[tuple[str, str], ...] = (("mpc", "MPC: collision"), ("campc", "CAMPC: avoids"))
"""(controller name, label) of the left and right panels."""
OUT = REPO_ROOT / "docs" / "figures" / "case1_mpc_vs_campc.gif"
RENDER_SIZE = (480, 360)
"""Width and height of the rendered frames, pixels (the environment's camera and field of view)."""
CROP = (105, 80, 375, 290)
"""The part of a rendered frame kept (left, top, right, bottom): the vehicle, its arms and both circles."""
FRAME_EVERY = 4
"""Keep every N-th control step (0.04 s each): 6.25 frames per second, played in real time."""
PALETTE_COLOURS = 48
"""Colours of each frame's adaptive palette."""
LABEL_HEIGHT = 26
"""Height of the label band above each panel, pixels."""
BORDER = 3
"""Width of a panel's border, pixels (red while its run reports a contact)."""
FONT_SIZE = 15
CONTACT_RGB = (220, 30, 30)
QUIET_RGB = (255, 255, 255)
TEXT_RGB = (20, 20, 20)
MAX_BYTES = 1_500_000
"""Largest accepted size of the written animation, bytes."""


class FrameGrabber(gym.Wrapper):
    """Keeps a frame after ``reset`` and after every ``every``-th step, with whether a contact happened since.

    Args:
        env: an environment made with ``render_mode="rgb_array"``.
        every: keep a frame every this many steps (and at the episode's end).

    Attributes:
        frames: the kept ``rgb_array`` frames.
        contact: per kept frame, whether any step since the previous kept frame reported a contact.
        times: per kept frame, the simulated time, s.
    """

    def __init__(self, env: gym.Env, every: int) -> None:
        super().__init__(env)
        self.every = int(every)
        self.frames: list[np.ndarray] = []
        self.contact: list[bool] = []
        self.times: list[float] = []
        self._steps = 0
        self._touched = False

    def reset(self, **kwargs: Any):
        """Reset the environment and keep the first frame."""
        obs, info = self.env.reset(**kwargs)
        self._steps, self._touched = 0, False
        self._keep(info)
        return obs, info

    def step(self, action):
        """Step the environment; keep a frame every ``every`` steps and at the episode's end."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._steps += 1
        self._touched = self._touched or info["contacts"] > 0
        if self._steps % self.every == 0 or terminated or truncated:
            self._keep(info)
        return obs, reward, terminated, truncated, info

    def _keep(self, info: dict) -> None:
        self.frames.append(self.env.render())
        self.contact.append(self._touched or info["contacts"] > 0)
        self.times.append(float(info["t"]))
        self._touched = False


def run_panel(name: str, every: int) -> tuple[FrameGrabber, dict]:
    """One seeded episode of a named controller with its frames; returns the grabber and the episode metrics."""
    width, height = RENDER_SIZE
    env = gym.make(ENV_ID, render_mode="rgb_array", render_width=width, render_height=height, **ENV_KWARGS)
    try:
        grabber = FrameGrabber(env, every)
        episode = run_episode(grabber, make_controller(name, env), SEED)
    finally:
        env.close()
    return grabber, episode


def check_labels(episodes: dict[str, dict]) -> None:
    """Refuse to write labels that the runs contradict (plain MPC must touch, CAMPC must not).

    Raises:
        RuntimeError: naming the contradicted label.
    """
    if episodes["mpc"]["contacts"] == 0:
        raise RuntimeError("the plain MPC's Case 1 run has no contact: the label 'MPC: collision' would be false")
    if episodes["campc"]["contacts"] != 0:
        raise RuntimeError(f"CAMPC's Case 1 run has {episodes['campc']['contacts']} contact steps: not 'avoids'")


def panel(frame: np.ndarray, label: str, t: float, contact: bool, font: ImageFont.ImageFont) -> Image.Image:
    """A cropped frame under its label band (label, time, a contact flag), framed in red on a contact."""
    view = Image.fromarray(frame).crop(CROP)
    out = Image.new("RGB", (view.width, view.height + LABEL_HEIGHT), QUIET_RGB)
    out.paste(view, (0, LABEL_HEIGHT))
    draw = ImageDraw.Draw(out)
    draw.text((2 * BORDER, BORDER), label, fill=TEXT_RGB, font=font)
    status = f"t = {t:4.1f} s" + ("  CONTACT" if contact else "")
    width = draw.textlength(status, font=font)
    draw.text((out.width - width - 2 * BORDER, BORDER), status, fill=CONTACT_RGB if contact else TEXT_RGB, font=font)
    if contact:
        draw.rectangle((0, 0, out.width - 1, out.height - 1), outline=CONTACT_RGB, width=BORDER)
    return out


def compose(grabbers: dict[str, FrameGrabber]) -> list[Image.Image]:
    """The side-by-side frames (both runs have the same length: 500 steps, no termination)."""
    font = ImageFont.load_default(size=FONT_SIZE)
    n = min(len(g.frames) for g in grabbers.values())
    frames = []
    for k in range(n):
        parts = [
            panel(grabbers[name].frames[k], label, grabbers[name].times[k], grabbers[name].contact[k], font)
            for name, label in PANELS
        ]
        row = Image.new("RGB", (sum(p.width for p in parts), parts[0].height), QUIET_RGB)
        x = 0
        for p in parts:
            row.paste(p, (x, 0))
            x += p.width
        frames.append(row.quantize(colors=PALETTE_COLOURS, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE))
    return frames


def write_gif(frames: list[Image.Image], out: Path, frame_ms: int) -> int:
    """Write the looping animation; returns its size in bytes."""
    out.parent.mkdir(parents=True, exist_ok=True)
    frames[0].save(out, save_all=True, append_images=frames[1:], duration=frame_ms, loop=0, optimize=True)
    return out.stat().st_size


def main(argv: list[str] | None = None) -> int:
    """Render both episodes, check the labels, write the GIF and report its size."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help=f"animation to write (default {OUT})")
    parser.add_argument("--every", type=int, default=FRAME_EVERY, help="keep every N-th control step")
    args = parser.parse_args(argv)
    if args.every < 1:
        parser.error(f"--every must be at least 1, got {args.every}")
    grabbers, episodes = {}, {}
    for name, _ in PANELS:
        grabbers[name], episodes[name] = run_panel(name, args.every)
        ep = episodes[name]
        print(f"{name}: {ep['contacts']} contact steps, min distance {ep['min_distance']:.4f} m, {ep['steps']} steps")
    check_labels(episodes)
    frame_ms = round(1000 * args.every * grabbers["mpc"].env.unwrapped.control_dt)  # real time
    size = write_gif(compose(grabbers), args.out, frame_ms)
    print(f"wrote {args.out} ({size / 1e6:.2f} MB, {len(grabbers['mpc'].frames)} frames)")
    if size > MAX_BYTES:
        print(f"error: {size} bytes exceed the {MAX_BYTES} allowed; raise --every", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
