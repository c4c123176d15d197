"""The actor of a trained agent as a prior: read from a weights-only export for fine-tuning (TD3-prior).

A weights-only export (``agents.export``: ``agent.json`` + ``policy.pt``, the policy's ``state_dict`` saved with
``torch.save``) of a TD3-family agent holds its actor under the keys ``actor.*``. :func:`load_prior_actor`
returns those weights, for :class:`agents.algos.td3_prior.TD3Prior` to start its actor from and to hold it near.
The files are read here by name (``agents.export`` imports this package, so this module cannot import it); only
``torch.load(weights_only=True)`` touches the weights, nothing is unpickled.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import torch

AGENT_JSON = "agent.json"
"""The export's record (``agents.export.weights.AGENT_JSON``)."""
WEIGHTS_FILE = "policy.pt"
"""The export's weights (``agents.export.weights.WEIGHTS_FILE``; a test checks that the names agree)."""
ACTOR_PREFIX = "actor."


def load_prior_actor(path: str | Path) -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
    """The actor weights and the ``agent.json`` record of a weights-only export, checked for use as a prior.

    Args:
        path: The export's folder.

    Returns:
        ``(state_dict of the actor, the agent.json record)``.

    Raises:
        ValueError: No export at ``path``, an unreadable file, an export without actor weights (not a TD3-family
            agent), or one trained with observation normalisation or an ``action_scale`` other than 1 (a prior
            must act on the raw observation in the action's own units, as the fine-tuned actor does).
    """
    folder = Path(path)
    if not (folder / AGENT_JSON).is_file() or not (folder / WEIGHTS_FILE).is_file():
        raise ValueError(
            f"prior_policy {str(path)!r} is not a weights-only agent export ({AGENT_JSON} + {WEIGHTS_FILE})"
        )
    try:
        record = json.loads((folder / AGENT_JSON).read_text(encoding="utf-8"))
        state = torch.load(folder / WEIGHTS_FILE, map_location="cpu", weights_only=True)
    except (OSError, ValueError, RuntimeError) as exc:
        raise ValueError(f"prior_policy {str(path)!r}: cannot read the export ({exc})") from None
    actor = {key[len(ACTOR_PREFIX) :]: value for key, value in state.items() if key.startswith(ACTOR_PREFIX)}
    if not actor:
        raise ValueError(f"prior_policy {str(path)!r} holds no actor weights (a TD3-family agent's export is needed)")
    if (record.get("normalization") or {}).get("norm_obs"):
        raise ValueError(
            f"prior_policy {str(path)!r} was trained with observation normalisation, which a prior cannot use"
        )
    if float(record.get("action_scale", 1.0)) != 1.0:
        raise ValueError(f"prior_policy {str(path)!r} has action_scale {record['action_scale']}; a prior needs 1.0")
    return actor, record
