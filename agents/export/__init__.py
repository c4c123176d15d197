"""Trained agents for evaluation: loading (:func:`load_agent`), and a weights-only export format that never unpickles.

Two ways to get an :class:`AgentController` (``reset(seed)``, ``predict(obs, info) -> action``,
deterministic, VecNormalize observation statistics applied without a VecEnv):

* :func:`load_agent` on a run directory or an SB3 zip. SB3 zips and VecNormalize ``.pkl`` files contain
  pickles (arbitrary code on load), so this goes through :func:`load_sb3_zip`, which refuses unless the
  caller passes ``trust=True`` or the file lies inside the repository's ``trained_agents/`` folder.
* :func:`load_weights_only` on a directory written by :func:`export_agent`::

      agent.json          format, algo, env id/kwargs, policy alias, policy_kwargs (plain data, class names
                          whitelisted), observation/action spaces (shape, dtype, bounds), normalisation
                          settings, action_scale, the composition (residual_base, residual_scale,
                          safety_filter: :mod:`uvdms_gym.residual`), num_timesteps, package versions,
                          SHA-256 of the two files below
      policy.pt           ``torch.save(policy.state_dict())``: tensors only, loaded with
                          ``torch.load(..., weights_only=True)``
      normalization.npz   ``obs_mean``, ``obs_var`` (only when observations are normalised), loaded with
                          ``numpy.load(..., allow_pickle=False)``
      learning_curve.json the run's evaluation metrics against steps (:mod:`agents.common.learning_curve`; if recorded)
      meta.json           the run's record: seeds, versions, git revision, each segment's command, steps and
                          wall time (:mod:`agents.training.rundir`; if recorded). Neither is read to rebuild the policy
                          nor part of the agent's checksum.

  The policy is rebuilt from the JSON by constructing the algorithm's policy class with the saved spaces
  and keyword arguments; no file of the export is unpickled.

Modules: :mod:`~agents.export.controller` (the controller and the errors), :mod:`~agents.export.sb3` (trust-gated SB3
zips), :mod:`~agents.export.weights` (the weights-only format), :mod:`~agents.export.agent` (the loader that
dispatches on the folder's format, and :func:`export_agent`).
"""

from agents.export.agent import export_agent, load_agent
from agents.export.controller import (
    SHIPPED_MODEL,
    SHIPPED_STATS,
    AgentController,
    EnvMismatchWarning,
    ExportFormatError,
    ObsNormalizer,
    UntrustedFileError,
    Which,
    check_agent,
    recorded_composition,
)
from agents.export.sb3 import (
    TRUSTED_DIR,
    is_trusted_path,
    load_sb3_agent,
    load_sb3_zip,
    load_vecnormalize_stats,
    zip_algo,
)
from agents.export.weights import (
    AGENT_JSON,
    FORMAT_NAME,
    FORMAT_VERSION,
    NORMALIZATION_FILE,
    RUN_META,
    WEIGHTS_FILE,
    copy_run_meta,
    export_controller,
    load_weights_only,
)

__all__ = [
    "AGENT_JSON",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "NORMALIZATION_FILE",
    "RUN_META",
    "SHIPPED_MODEL",
    "SHIPPED_STATS",
    "TRUSTED_DIR",
    "WEIGHTS_FILE",
    "AgentController",
    "EnvMismatchWarning",
    "ExportFormatError",
    "ObsNormalizer",
    "UntrustedFileError",
    "Which",
    "check_agent",
    "copy_run_meta",
    "export_agent",
    "export_controller",
    "is_trusted_path",
    "load_agent",
    "load_sb3_agent",
    "load_sb3_zip",
    "load_vecnormalize_stats",
    "load_weights_only",
    "recorded_composition",
    "zip_algo",
]
