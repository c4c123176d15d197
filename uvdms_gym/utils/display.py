"""Whether PyBullet's GUI can open here, checked *before* connecting.

PyBullet's ``connect(GUI)`` on Linux without a reachable X server prints ``cannot connect to X server`` and
calls the C ``exit()``: the Python process ends with status 1 and no exception to catch (Gymnasium's
``check_env`` and ``uvdms demo --gui`` died that way). :func:`require_display` raises
:class:`DisplayUnavailableError` instead; :class:`~uvdms_gym.physics.sim.UVDMSSim` calls it before a GUI connect, and
the environments list ``"human"`` in their instance's ``metadata["render_modes"]`` only where
:func:`gui_unavailable_reason` finds a display.

The check [D]: on macOS and Windows PyBullet's GUI opens a native window and needs no X server (no check).
Elsewhere (Linux, BSD) it needs ``$DISPLAY`` and an X server answering on it: ``:N`` (or ``unix:N``) is
probed by connecting to the local socket ``/tmp/.X11-unix/XN`` (abstract name first, as Xorg and Xwayland
listen on both), ``host:N`` by a TCP connection to port ``6000 + N`` (SSH X forwarding: ``localhost:10``), and
a ``$DISPLAY`` that is a socket path (XQuartz) by connecting to that path. A display that accepts the
connection but refuses the client (``xhost``) or lacks OpenGL is not detected.
"""

from __future__ import annotations

import functools
import os
import re
import socket
import sys
from collections.abc import Mapping

PROBE_TIMEOUT = 1.0
"""Seconds allowed for the TCP probe of a remote ``$DISPLAY``."""

_DISPLAY_RE = re.compile(r"^(?P<host>[^:]*):(?P<number>\d+)(?:\.\d+)?$")


class DisplayUnavailableError(RuntimeError):
    """PyBullet's GUI cannot open: no display (the message says why and what to use instead)."""


def _connects(family: int, address: object) -> bool:
    try:
        with socket.socket(family, socket.SOCK_STREAM) as sock:
            sock.settimeout(PROBE_TIMEOUT)
            sock.connect(address)
        return True
    except OSError:
        return False


def gui_unavailable_reason(environ: Mapping[str, str] | None = None, platform: str | None = None) -> str | None:
    """Why PyBullet's GUI cannot open here, or ``None`` if it can (as far as the checks above can tell).

    Args:
        environ: The environment variables (default ``os.environ``).
        platform: ``sys.platform`` (default the running one).

    Returns:
        A sentence naming the problem, or ``None``.
    """
    environ = os.environ if environ is None else environ
    platform = sys.platform if platform is None else platform
    if platform == "darwin" or platform.startswith(("win", "cygwin")):
        return None
    display = environ.get("DISPLAY", "")
    if not display:
        return "no display: $DISPLAY is not set (a headless machine, or an SSH session without X forwarding)"
    if display.startswith("/"):  # XQuartz-style socket path
        ok = hasattr(socket, "AF_UNIX") and _connects(socket.AF_UNIX, display.split(":")[0])
        return None if ok else f"no X server answers on $DISPLAY={display}"
    match = _DISPLAY_RE.match(display)
    if match is None:
        return f"$DISPLAY={display!r} is not of the form [host]:N[.S]"
    host, number = match["host"], int(match["number"])
    if host in ("", "unix"):
        path = f"/tmp/.X11-unix/X{number}"
        if hasattr(socket, "AF_UNIX") and (
            (platform.startswith("linux") and _connects(socket.AF_UNIX, "\0" + path)) or _connects(socket.AF_UNIX, path)
        ):
            return None
        return f"no X server answers on $DISPLAY={display} (nothing listens on {path})"
    if _connects(socket.AF_INET, (host, 6000 + number)) or _connects(socket.AF_INET6, (host, 6000 + number)):
        return None
    return f"no X server answers on $DISPLAY={display} (TCP port {6000 + number} of {host} refused or timed out)"


@functools.lru_cache(maxsize=8)
def _cached_reason(platform: str, display: str) -> str | None:
    return gui_unavailable_reason({"DISPLAY": display} if display else {}, platform)


def gui_available() -> bool:
    """Whether PyBullet's GUI can open here (:func:`gui_unavailable_reason`, cached per ``$DISPLAY`` value)."""
    return _cached_reason(sys.platform, os.environ.get("DISPLAY", "")) is None


def require_display() -> None:
    """Raise :class:`DisplayUnavailableError` if PyBullet's GUI cannot open here.

    Raises:
        DisplayUnavailableError: With the reason of :func:`gui_unavailable_reason`.
    """
    reason = gui_unavailable_reason()
    if reason is not None:
        raise DisplayUnavailableError(
            f"PyBullet's GUI cannot open: {reason}. Render off-screen instead (render_mode='rgb_array', "
            "uvdms demo --png FILE), or run where a display is available"
        )
