"""
Read and write identified-parameter files (JSON).

They are written by ``mr-damper-identify --out`` and the identifier node, and read by the
inverse model, the quarter car and the identifier after a restart.

Format::

    {
      "model": "kwok-current",
      "parameters": {"c0": 310.2, "c1": 1020.5, ...},     # name -> value, SI units
      "model_options": {"i_ref_a": 2.0},                   # model constants
      "current_min_a": 0.0, "current_max_a": 2.0,          # current range the fit covers [A]
      "metrics": {"rmse_n": 12.3, ...},                    # fit quality (metrics.fit_metrics)
      "valid": true,                                       # passed the quality threshold
      "seed": 1, "source": "rig_test.csv"
    }

Only ``model`` and ``parameters`` are required; loading checks that every parameter of the
model is present and finite and raises :class:`~mr_damper_model.io.data.DataError` naming the file.
"""
from dataclasses import asdict, dataclass, field
import json
import math
import os
from pathlib import Path
import tempfile

from mr_damper_common.contract import IdentifiedSet
from mr_damper_model.io.data import DataError
from mr_damper_model.models import get_model
from mr_damper_model.models.plant import make_plant


@dataclass
class ParamsFile:
    """Contents of a parameter file (see the module docstring for the fields)."""

    model: str
    parameters: dict
    model_options: dict = field(default_factory=dict)
    current_min_a: float = math.nan
    current_max_a: float = math.nan
    metrics: dict = field(default_factory=dict)
    valid: bool = True
    seed: object = None
    source: str = ''

    def to_json_dict(self):
        """Return the JSON-ready dictionary."""
        return asdict(self)


def _as_params_file(obj):
    if isinstance(obj, ParamsFile):
        return obj
    d = obj.to_json_dict() if hasattr(obj, 'to_json_dict') else dict(obj)
    known = ParamsFile.__dataclass_fields__
    return ParamsFile(**{k: v for k, v in d.items() if k in known})


def save_params(path, result):
    """
    Write identified parameters to a JSON file, atomically (write then rename).

    Parameters
    ----------
    path : str or Path
        Output file.
    result : IdentificationResult, ParamsFile or dict
        Anything with ``model`` and ``parameters`` (an object with ``to_json_dict()`` works).

    """
    pf = _as_params_file(result)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(pf.to_json_dict(), indent=2, sort_keys=False, default=_json_default)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix='.tmp')
    try:
        with os.fdopen(fd, 'w') as fh:
            fh.write(text + '\n')
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _json_default(obj):
    if hasattr(obj, 'tolist'):
        return obj.tolist()
    raise TypeError(f'{type(obj).__name__} is not JSON serialisable')


def load_params(path, *, model=None):
    """
    Read and check a parameter file.

    Parameters
    ----------
    path : str or Path
        JSON file written by :func:`save_params`.
    model : str, optional
        Required model name (e.g. ``'kwok-current'``); another model is an error.

    Returns
    -------
    ParamsFile

    Raises
    ------
    DataError
        Unreadable or invalid JSON, missing keys, wrong model, missing or non-finite parameters.

    """
    name = str(path)
    try:
        with open(path) as fh:
            raw = json.load(fh)
    except OSError as exc:
        raise DataError(f'{name}: cannot read parameter file ({exc.strerror or exc})') from None
    except ValueError as exc:
        raise DataError(f'{name}: not valid JSON ({exc})') from None
    if not isinstance(raw, dict):
        raise DataError(f'{name}: expected a JSON object with "model" and "parameters"')
    for key in ('model', 'parameters'):
        if key not in raw:
            raise DataError(f'{name}: missing "{key}"')
    if model is not None and raw['model'] != model:
        raise DataError(f'{name}: model is "{raw["model"]}", expected "{model}"')
    if not isinstance(raw['parameters'], dict):
        raise DataError(f'{name}: "parameters" must be an object of name -> value')
    try:
        spec = get_model(raw['model'], **dict(raw.get('model_options') or {}))
        expected = spec.param_names
    except (ImportError, KeyError, ValueError) as exc:
        raise DataError(f'{name}: unknown model "{raw["model"]}" ({exc})') from None
    missing = [p for p in expected if p not in raw['parameters']]
    if missing:
        raise DataError(f'{name}: missing parameter(s) {", ".join(missing)} '
                        f'for model {raw["model"]}')
    params = {}
    for p in expected:
        try:
            value = float(raw['parameters'][p])
        except (TypeError, ValueError):
            raise DataError(f'{name}: parameter {p} is not a number') from None
        if not math.isfinite(value):
            raise DataError(f'{name}: parameter {p} is {value} (must be finite)')
        params[p] = value
    pf = _as_params_file(raw)
    pf.parameters = params
    pf.current_min_a = _float_or_nan(pf.current_min_a)
    pf.current_max_a = _float_or_nan(pf.current_max_a)
    return pf


def load_identified_set(path):
    """
    Read a kwok-current parameter file as the set it holds.

    Parameters
    ----------
    path : str or Path
        JSON file of a ``kwok-current`` model (:func:`load_params`).

    Returns
    -------
    mr_damper_common.contract.IdentifiedSet
        :meth:`~mr_damper_common.contract.IdentifiedSet.from_params_file` of the file.

    Raises
    ------
    DataError
        As :func:`load_params`.

    """
    return IdentifiedSet.from_params_file(load_params(path, model='kwok-current'))


def load_plant(name='spencer', params=None, **options):
    """
    Build a streaming plant from a parameter file, by default the thesis-like "true" damper.

    Parameters
    ----------
    name : {'spencer', 'kwok-current'}
        Plant model.
    params : dict, sequence, str, path or None
        A parameter file of the plant (:func:`load_params` format: the rig's and the car's
        ``truth_file``), or parameters as ``make_plant`` takes them; None or ``''``: the
        preset of the model (``presets.spencer_thesis_like()`` or
        ``presets.thesis_kwok_current()``).
    **options
        Keyword options of the plant (see ``mr_damper_model.models.plant.make_plant``).

    Returns
    -------
    DamperPlant

    Raises
    ------
    DataError
        The file cannot be read or holds another model.

    """
    if isinstance(params, str) or hasattr(params, '__fspath__'):
        params = load_params(params, model=name).parameters if str(params) else None
    return make_plant(name, params, **options)


def _float_or_nan(v):
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan
