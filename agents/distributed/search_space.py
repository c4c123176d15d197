"""Hyperparameter search spaces of ``uvdms tune``: RL-Zoo-style YAML files loaded into strict dataclasses.

``train_configs/search_spaces/<algo>.yml`` holds the space of one algorithm: the parameter names and ranges of
RL Baselines3 Zoo's ``rl_zoo3/hyperparams_opt.py`` samplers, written as data instead of code. Each top-level key
is an Optuna parameter; its mapping (:class:`ParamSpace`) says how to sample it and which config key it sets::

    batch_size_pow: {type: int, low: 2, high: 10, key: batch_size, transform: pow2}      # batch_size = 2**k
    one_minus_gamma: {type: float, low: 1.0e-4, high: 0.03, log: true, key: gamma, transform: one_minus}
    learning_rate: {type: float, low: 1.0e-5, high: 0.002, log: true}                   # key defaults to the name
    clip_range: {type: categorical, choices: [0.1, 0.2, 0.3, 0.4]}
    net_arch:                                                                           # named choices
      type: categorical
      choices: [tiny, small]
      values: {tiny: {pi: [64], vf: [64]}, small: {pi: [64, 64], vf: [64, 64]}}
      key: policy_kwargs.net_arch                                                       # one key of policy_kwargs
    train_freq: {type: int, low: 1, high: 10, also: [gradient_steps]}                    # sets both keys

The file is read with ``yaml.safe_load``; unknown keys, wrong types and inconsistent ranges are
:class:`~agents.config.ConfigError`. The config keys a space sets are checked against the algorithm when
``uvdms tune`` starts (:func:`agents.distributed.tune.tune` validates a sample with :func:`agents.config.load_config`).
A parameter whose keys are fixed by ``--hyperparams`` is left out of the search (:meth:`SearchSpace.without`).
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from agents.common.paths import train_configs_dir
from agents.config.typecheck import ConfigError, TypeChecker, check_known_keys, tname

PARAM_TYPES: tuple[str, ...] = ("float", "int", "categorical")
"""Values of ``type``: Optuna's ``suggest_float``, ``suggest_int``, ``suggest_categorical``."""
TRANSFORMS: tuple[str, ...] = ("identity", "pow2", "one_minus")
"""Values of ``transform``: the config value is the sample, ``2 ** sample`` (int) or ``1 - sample`` (float)."""
POLICY_KWARGS_PREFIX = "policy_kwargs."
"""A ``key`` starting with this sets one key of ``policy_kwargs`` (merged into the configuration's)."""
SEARCH_SPACES_DIR = "search_spaces"
"""Folder of the search-space files inside ``train_configs/``."""

_CHECKER = TypeChecker()


@dataclasses.dataclass(frozen=True)
class ParamSpace:
    """How one Optuna parameter is sampled and which config keys it sets.

    Attributes:
        name: The Optuna parameter name (the YAML key).
        type: ``float``, ``int`` or ``categorical``.
        low: Lower bound (``float``/``int``).
        high: Upper bound, inclusive (``float``/``int``).
        log: Sample on a log scale (``float``/``int``; needs ``low > 0``).
        choices: The categories (``categorical``): null, booleans, numbers or strings.
        values: Config value of each category (``categorical`` with named choices such as ``small``); every
            choice must have one. Without it the category itself is the value.
        key: Config key set (default: ``name``); ``policy_kwargs.<k>`` sets one key of ``policy_kwargs``.
        transform: ``identity``, ``pow2`` (``int``: ``2 ** sample``) or ``one_minus`` (``float``: ``1 - sample``).
        also: More config keys set to the same value (RL Zoo's ``gradient_steps = train_freq``).
    """

    name: str
    type: str
    low: float | None = None
    high: float | None = None
    log: bool = False
    choices: list[Any] | None = None
    values: dict[str, Any] | None = None
    key: str | None = None
    transform: str = "identity"
    also: list[str] = dataclasses.field(default_factory=list)

    @property
    def keys(self) -> tuple[str, ...]:
        """Every config key the parameter sets."""
        return (self.key or self.name, *self.also)

    def suggest(self, trial: Any) -> Any:
        """Sample the parameter with an Optuna ``trial`` (define-by-run) and return the sample."""
        if self.type == "float":
            return trial.suggest_float(self.name, float(self.low), float(self.high), log=self.log)
        if self.type == "int":
            return trial.suggest_int(self.name, int(self.low), int(self.high), log=self.log)
        return trial.suggest_categorical(self.name, list(self.choices or ()))

    def config_value(self, sample: Any) -> Any:
        """The config value of a sample (named choice looked up, transform applied)."""
        if self.values is not None:
            return self.values[sample]
        if self.transform == "pow2":
            return 2 ** int(sample)
        if self.transform == "one_minus":
            return 1.0 - float(sample)
        return sample

    def example(self) -> Any:
        """A valid sample (the lower bound or the first choice), used to check the config keys."""
        if self.type == "categorical":
            return (self.choices or [None])[0]
        return int(self.low) if self.type == "int" else float(self.low)


def _check_param(p: ParamSpace, where: str) -> None:
    """Consistency of one parameter (types of the fields are checked by the loader)."""
    where = f"{where}: parameter {p.name!r}"
    if p.type not in PARAM_TYPES:
        raise ConfigError(f"{where}: type must be one of {PARAM_TYPES}, got {p.type!r}")
    if p.transform not in TRANSFORMS:
        raise ConfigError(f"{where}: transform must be one of {TRANSFORMS}, got {p.transform!r}")
    if p.type == "categorical":
        _check_categorical(p, where)
    else:
        _check_numeric(p, where)
    for key in p.keys:
        name = key.removeprefix(POLICY_KWARGS_PREFIX)
        if not name.isidentifier() or key in ("policy_kwargs", "n_timesteps"):
            raise ConfigError(f"{where}: {key!r} is not a config key this can set (a key or policy_kwargs.<key>)")


def _check_categorical(p: ParamSpace, where: str) -> None:
    """A categorical parameter: distinct plain choices, no bounds, no transform, ``values`` naming the choices."""
    if not p.choices:
        raise ConfigError(f"{where}: a categorical parameter needs a non-empty 'choices' list")
    if any(c is not None and not isinstance(c, bool | int | float | str) for c in p.choices):
        raise ConfigError(f"{where}: choices must be null, booleans, numbers or strings (name others in 'values')")
    if len(set(map(repr, p.choices))) != len(p.choices):
        raise ConfigError(f"{where}: a choice is listed twice")
    if p.low is not None or p.high is not None or p.log:
        raise ConfigError(f"{where}: 'low', 'high' and 'log' are for float and int parameters")
    if p.transform != "identity":
        raise ConfigError(f"{where}: transform {p.transform!r} is for numeric parameters")
    if p.values is not None and set(p.values) != {str(c) for c in p.choices}:
        raise ConfigError(f"{where}: 'values' must name exactly the choices {p.choices}")


def _check_numeric(p: ParamSpace, where: str) -> None:
    """A float or int parameter: bounds low < high (integers for int, > 0 on a log scale), a fitting transform."""
    if p.low is None or p.high is None or not p.low < p.high:
        raise ConfigError(f"{where}: needs numbers low < high, got low={p.low!r} high={p.high!r}")
    if p.type == "int" and (p.low != int(p.low) or p.high != int(p.high)):
        raise ConfigError(f"{where}: an int parameter needs integer bounds")
    if p.log and p.low <= 0:
        raise ConfigError(f"{where}: log scale needs low > 0")
    if p.choices is not None or p.values is not None:
        raise ConfigError(f"{where}: 'choices' and 'values' are for categorical parameters")
    if p.transform == "pow2" and p.type != "int":
        raise ConfigError(f"{where}: transform pow2 needs an int parameter")
    if p.transform == "one_minus" and p.type != "float":
        raise ConfigError(f"{where}: transform one_minus needs a float parameter")


@dataclasses.dataclass(frozen=True)
class SearchSpace:
    """The parameters of one algorithm's search.

    Attributes:
        params: The parameters, in file order (the order Optuna samples them).
        source: Where they were read (for messages).
    """

    params: tuple[ParamSpace, ...]
    source: str = "<search space>"

    def define_by_run(self, trial: Any) -> None:
        """Optuna define-by-run function (``ray.tune.search.optuna.OptunaSearch(space=...)``)."""
        for p in self.params:
            p.suggest(trial)

    def hyperparams(self, sample: Mapping[str, Any], policy_kwargs: Mapping[str, Any]) -> dict[str, Any]:
        """Config overrides for a sample ``{name: value}``; ``policy_kwargs.*`` keys merged into ``policy_kwargs``.

        Args:
            sample: One value per parameter (Optuna's names).
            policy_kwargs: The configuration's ``policy_kwargs`` the sampled keys are merged into.
        """
        out: dict[str, Any] = {}
        merged = dict(policy_kwargs)
        for p in self.params:
            value = p.config_value(sample[p.name])
            for key in p.keys:
                if key.startswith(POLICY_KWARGS_PREFIX):
                    merged[key.removeprefix(POLICY_KWARGS_PREFIX)] = value
                else:
                    out[key] = value
        if any(k.startswith(POLICY_KWARGS_PREFIX) for p in self.params for k in p.keys):
            out["policy_kwargs"] = merged
        return out

    def example(self) -> dict[str, Any]:
        """A valid sample (:meth:`ParamSpace.example` of every parameter)."""
        return {p.name: p.example() for p in self.params}

    def without(self, fixed: Iterable[str]) -> SearchSpace:
        """The space without the parameters that set one of the ``fixed`` config keys (``--hyperparams``)."""
        fixed = set(fixed)
        return dataclasses.replace(self, params=tuple(p for p in self.params if not set(p.keys) & fixed))


def default_search_space_path(algo: str) -> Path:
    """``train_configs/search_spaces/<algo>.yml`` (the installed copy or the checkout's, :mod:`agents.common.paths`)."""
    return train_configs_dir() / SEARCH_SPACES_DIR / f"{algo}.yml"


def load_search_space(path: str | Path) -> SearchSpace:
    """Read a search-space file (see the module docstring) with ``yaml.safe_load``.

    Raises:
        ConfigError: A missing or malformed file, an unknown key, a wrong type or an inconsistent parameter.
    """
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read search space ({exc})") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: invalid YAML: {' '.join(str(exc).split())}") from exc
    if not isinstance(data, dict) or not data:
        raise ConfigError(f"{path}: a search space is a non-empty mapping of parameter name -> spec, got {tname(data)}")
    params = [_read_param(path, name, spec) for name, spec in data.items()]
    keys = [key for p in params for key in p.keys]
    for key in keys:
        if keys.count(key) > 1:
            raise ConfigError(f"{path}: config key {key!r} is set by two parameters")
    return SearchSpace(tuple(params), source=str(path))


def _read_param(path: Path, name: Any, spec: Any) -> ParamSpace:
    """One parameter of a search-space file, checked (keys, types, consistency)."""
    where = f"{path}: parameter {name!r}"
    if not isinstance(name, str) or not name.isidentifier():
        raise ConfigError(f"{path}: parameter name {name!r} must be an identifier")
    if not isinstance(spec, dict):
        raise ConfigError(f"{where}: expected a mapping, got {tname(spec)}")
    fields = [f.name for f in dataclasses.fields(ParamSpace) if f.name != "name"]
    check_known_keys(spec, fields, where, "parameter keys")
    if "type" not in spec:
        raise ConfigError(f"{where}: missing 'type' (one of {PARAM_TYPES})")
    hints = typing.get_type_hints(ParamSpace)
    values = {key: _CHECKER.validate(value, hints[key], where, key) for key, value in spec.items()}
    for bound in ("low", "high"):
        if values.get(bound) is not None:
            values[bound] = float(values[bound]) if isinstance(values[bound], str) else values[bound]
    param = ParamSpace(name=name, **values)
    _check_param(param, str(path))
    return param
