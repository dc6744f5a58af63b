"""``run.yaml``: parsing, JSON-Schema validation and the checks that need no samples.

A run is a folder ``<run_id>/`` holding ``run.yaml`` and one recording file
(CONTRACTS.md section 1). :func:`load_run` turns it into a frozen :class:`Run`;
anything wrong raises :class:`~bouncelab.errors.BouncelabError` naming ``run.yaml``
(key problems) or the folder (name problems). Checks that need the recording's
header or samples (sample rate, channels present, steps inside the recording) are
in :mod:`bouncelab.runs.readers`.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import jsonschema
import yaml

from bouncelab.errors import BouncelabError

RUN_YAML = "run.yaml"
RUN_ID_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
AUDIO_SUFFIXES = (".flac", ".wav")
SUFFIXES = (".flac", ".wav", ".csv", ".npz", ".tdms")
ROLES = ("continuity", "drive", "accel")
DEFAULT_SETTLE_CYCLES = 10
DEFAULT_FULL_SCALE_V = 1.0
DEFAULT_CONTACT_LEVEL = "auto"

# keys of CONTRACTS.md section 1; every other key goes to ``Run.extra``
KNOWN_KEYS = frozenset(
    {
        "format_version",
        "kind",
        "recording",
        "sample_rate_hz",
        "channels",
        "full_scale_v",
        "contact_level",
        "mass_kg",
        "drive_frequency_hz",
        "gamma_steps",
        "settle_cycles",
        "drop_height_m",
        "release_t_s",
        "accel_v_per_g",
        "source",
        "description",
    }
)

#: keys beyond the contract that bouncelab reads (kept in ``Run.extra``, checked here):
#: the drive reference's lead over the plate (rad, docs/flights.md) and the local
#: gravity of a drop test (m/s^2, docs/flights.md "Calibration")
EXTENSION_KEYS = frozenset({"drive_phase_offset_rad", "g_m_s2"})


@dataclass(frozen=True)
class Run:
    """A parsed, schema-checked ``run.yaml`` and where its recording is.

    Units are in the names (s, Hz, kg, m, V). Times (``gamma_steps`` starts,
    ``release_t_s``) are on the recording's time axis: ``index / sample_rate_hz``,
    or the ``time_s`` column when the recording has one.

    Attributes
    ----------
    run_id : str
        The folder name.
    path : Path
        The run folder, as given.
    kind : str
        ``"sweep"`` or ``"drop"``.
    recording_path : Path
        The recording file (inside ``path``).
    sample_rate_hz : float
    channels : dict[str, int | str]
        Role (``continuity``, ``drive``, ``accel``) -> channel: 0-based index for
        audio, column / array name for CSV / NPZ, ``"group/channel"`` for TDMS.
        Only the roles of the contract; others are in ``extra_channels``.
    full_scale_v : float
        Volts of an audio sample value of 1.0 (default 1.0; unused for other formats).
    contact_level : str
        ``"low"``, ``"high"`` or ``"auto"`` (default): continuity level meaning contact.
    gamma_steps : list[tuple[float, float]]
        ``(t_s, gamma)`` per step, strictly increasing in ``t_s``; ``[]`` for drops.
    settle_cycles : int
        Drive cycles discarded after each step start (default 10).
    extra : dict
        Unknown top-level keys, kept and ignored.
    """

    run_id: str
    path: Path
    kind: str
    recording_path: Path
    sample_rate_hz: float
    channels: dict[str, int | str]
    full_scale_v: float = DEFAULT_FULL_SCALE_V
    contact_level: str = DEFAULT_CONTACT_LEVEL
    mass_kg: float | None = None
    drive_frequency_hz: float | None = None
    gamma_steps: list[tuple[float, float]] = field(default_factory=list)
    settle_cycles: int = DEFAULT_SETTLE_CYCLES
    drop_height_m: float | None = None
    release_t_s: float | None = None
    accel_v_per_g: float | None = None
    source: str | None = None
    description: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    extra_channels: dict[str, Any] = field(default_factory=dict)

    @property
    def yaml_path(self) -> Path:
        """The ``run.yaml`` file."""
        return self.path / RUN_YAML

    @property
    def format(self) -> str:
        """Recording format from the extension: flac, wav, csv, npz or tdms."""
        return self.recording_path.suffix.lower().lstrip(".")

    @property
    def is_audio(self) -> bool:
        """True for FLAC and WAV recordings (channel indices, ``full_scale_v``)."""
        return self.recording_path.suffix.lower() in AUDIO_SUFFIXES


# --------------------------------------------------------------------------- YAML


class _RunYamlLoader(yaml.SafeLoader):
    """Safe loader that rejects duplicate keys and reads ``2e4`` as a float.

    PyYAML follows YAML 1.1, where ``2e4`` (no dot) is a string; lab users write it
    as a number, and YAML 1.2 agrees. A duplicate key would silently win in PyYAML;
    here it is an error, since one of the two values is a mistake.
    """


_RunYamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def _construct_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode) -> dict:
    seen: set = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in seen:
            mark = key_node.start_mark
            raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", mark)
        seen.add(key)
    return loader.construct_mapping(node, deep=True)


_RunYamlLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def read_run_yaml(path: Path) -> dict[str, Any]:
    """Parse ``run.yaml`` into a dict; YAML errors become one-line BouncelabErrors."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise BouncelabError(path, "run.yaml not found") from None
    except UnicodeDecodeError as exc:
        raise BouncelabError(path, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise BouncelabError(path, f"cannot read ({exc.strerror})") from None
    try:
        data = yaml.load(text, Loader=_RunYamlLoader)  # noqa: S506 (a SafeLoader subclass)
    except yaml.YAMLError as exc:
        raise BouncelabError(path, f"YAML syntax error: {_yaml_problem(exc)}") from None
    if not isinstance(data, dict):
        got = "an empty file" if data is None else f"a {type(data).__name__}"
        raise BouncelabError(path, f"must be a mapping of keys to values, got {got}")
    return data


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """One line from a PyYAML error: the problem and where it is."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"{problem}{where}"


# ------------------------------------------------------------------------- schema


@lru_cache(maxsize=1)
def run_schema() -> dict[str, Any]:
    """The JSON Schema of ``run.yaml`` (package data ``bouncelab/schemas/run.schema.json``)."""
    text = resources.files("bouncelab").joinpath("schemas/run.schema.json").read_text("utf-8")
    return json.loads(text)


@lru_cache(maxsize=1)
def _validator() -> jsonschema.protocols.Validator:
    schema = run_schema()
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(schema)


def check_schema(data: dict[str, Any], path: Path) -> None:
    """Raise one BouncelabError for the most relevant schema violation, if any."""
    errors = list(_validator().iter_errors(data))
    if not errors:
        return
    best = jsonschema.exceptions.best_match(errors)
    raise BouncelabError(path, _schema_problem(best, data))


def _where(parts) -> str:
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


def _schema_problem(err: jsonschema.ValidationError, data: dict[str, Any]) -> str:
    """A readable one-line statement of a schema error, naming the key."""
    where = _where(err.absolute_path)
    v, inst, val = err.validator, err.instance, err.validator_value
    if v == "required":
        missing = [k for k in val if isinstance(inst, dict) and k not in inst]
        key = _where([*err.absolute_path, missing[0]]) if missing else where
        kind = data.get("kind")
        if not err.absolute_path and key in ("drive_frequency_hz", "gamma_steps"):
            return f"required key {key!r} is missing (needed for kind {kind!r})"
        if not err.absolute_path and key in ("drop_height_m", "release_t_s"):
            return f"required key {key!r} is missing (needed for kind {kind!r})"
        return f"required key {key!r} is missing"
    if v == "enum":
        return f"{where}: {inst!r} is not one of {', '.join(map(repr, val))}"
    if v == "const":
        return f"{where}: must be {val!r}, got {inst!r}"
    if v == "exclusiveMinimum":
        return f"{where}: must be greater than {val}, got {inst!r}"
    if v == "minimum":
        return f"{where}: must be at least {val}, got {inst!r}"
    if v == "type":
        return f"{where or 'run.yaml'}: must be of type {val}, got {inst!r}"
    if v == "oneOf" and where.startswith("channels."):
        return f"{where}: must be a 0-based channel index or a non-empty name, got {inst!r}"
    if v == "not" and where == "accel_v_per_g":
        return f"{where}: must not be zero"
    return f"{where or 'run.yaml'}: {err.message}"


# -------------------------------------------------------------- semantic checks


def check_run_id(run_dir: Path) -> str:
    """The run id (folder name), checked against ``[A-Za-z0-9][A-Za-z0-9_.-]*``."""
    name = Path(os.path.abspath(run_dir)).name  # "." or "raw/x/" still give the real name
    if not RUN_ID_PATTERN.fullmatch(name):
        raise BouncelabError(
            run_dir,
            f"run folder name {name!r} does not match [A-Za-z0-9][A-Za-z0-9_.-]* "
            "(letters, digits, '_', '.', '-'; not starting with '_', '.' or '-')",
        )
    return name


def resolve_recording(run_dir: Path, recording: str, yaml_path: Path) -> Path:
    """The recording's path, checked to stay inside the run folder and to be supported.

    The check is on the path as written (no absolute path, no ``..`` leaving the
    folder); the file's existence is checked here too, so that a missing file names
    the file.
    """
    rel = Path(recording)
    norm = os.path.normpath(recording)
    if rel.is_absolute() or norm == ".." or norm.startswith(".." + os.sep) or norm == ".":
        raise BouncelabError(
            yaml_path, f"recording: {recording!r} must be a file name inside the run folder"
        )
    rec_path = run_dir / norm
    suffix = rec_path.suffix.lower()
    if suffix not in SUFFIXES:
        raise BouncelabError(
            yaml_path,
            f"recording: unsupported extension {suffix or '(none)'!r} of {recording!r}; "
            f"use one of {', '.join(SUFFIXES)}",
        )
    if not rec_path.is_file():
        raise BouncelabError(rec_path, "recording file not found (named in run.yaml)")
    return rec_path


def check_channels(channels: dict[str, Any], audio: bool, yaml_path: Path) -> dict[str, Any]:
    """Channel specs of the known roles, typed for the format (index for audio, else name)."""
    out: dict[str, int | str] = {}
    for role in ROLES:
        if role not in channels:
            continue
        spec = channels[role]
        if audio:
            if isinstance(spec, bool) or not isinstance(spec, int | float):
                raise BouncelabError(
                    yaml_path,
                    f"channels.{role}: audio recordings need a 0-based channel index, got {spec!r}",
                )
            out[role] = int(spec)
        else:
            if not isinstance(spec, str):
                raise BouncelabError(
                    yaml_path,
                    f"channels.{role}: this recording format needs a column / array / "
                    f"'group/channel' name, got {spec!r}",
                )
            out[role] = spec
    return out


def check_gamma_steps(steps: list[dict[str, Any]], yaml_path: Path) -> list[tuple[float, float]]:
    """``(t_s, gamma)`` pairs, finite and strictly increasing in ``t_s``."""
    out = [(float(s["t_s"]), float(s["gamma"])) for s in steps]
    for i, (t, g) in enumerate(out):
        if not (math.isfinite(t) and math.isfinite(g)):
            raise BouncelabError(yaml_path, f"gamma_steps[{i}]: t_s and gamma must be finite")
    for i in range(1, len(out)):
        if out[i][0] <= out[i - 1][0]:
            raise BouncelabError(
                yaml_path,
                f"gamma_steps must be sorted by t_s (strictly increasing): step {i} starts "
                f"at {out[i][0]:g} s, not after step {i - 1} at {out[i - 1][0]:g} s",
            )
    return out


def check_extension_keys(data: dict[str, Any], yaml_path: Path) -> None:
    """:data:`EXTENSION_KEYS` present in run.yaml must be finite numbers (``g_m_s2`` also
    positive): a value such as ``"0.6 rad"`` or ``.nan`` would otherwise fail deep in the
    extraction without naming run.yaml, or give NaN phases without a word."""
    for key in sorted(EXTENSION_KEYS & set(data)):
        value = data[key]
        if value is None:
            continue  # written but left empty: as if absent
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise BouncelabError(yaml_path, f"{key}: must be a number, got {value!r}")
        if not math.isfinite(value):
            raise BouncelabError(yaml_path, f"{key}: must be finite, got {value!r}")
        if key == "g_m_s2" and value <= 0:
            raise BouncelabError(yaml_path, f"{key}: must be positive, got {value!r}")


def _finite(data: dict[str, Any], key: str, yaml_path: Path) -> float | None:
    """Optional float key; schema checked the type, this rejects .inf and .nan."""
    if key not in data:
        return None
    value = float(data[key])
    if not math.isfinite(value):
        raise BouncelabError(yaml_path, f"{key}: must be finite, got {data[key]!r}")
    return value


# --------------------------------------------------------------------- public


def load_run(run_dir: str | Path) -> Run:
    """Read and check a run folder's ``run.yaml``; no samples are read.

    Checks: folder exists and its name matches the contract's pattern, ``run.yaml``
    parses (duplicate keys rejected), the JSON Schema (required keys by kind, types,
    ranges), finite numbers, channel spec types for the format, ``gamma_steps``
    strictly increasing, recording path inside the folder, supported extension,
    recording file present.

    Parameters
    ----------
    run_dir : str or Path
        The run folder ``raw/<run_id>/``.

    Returns
    -------
    Run

    Raises
    ------
    BouncelabError
        Naming ``run.yaml`` for key problems, the folder or the recording otherwise.
    """
    run_dir = Path(run_dir)
    if run_dir.is_file():
        raise BouncelabError(run_dir, "not a folder: give the run folder, not a file in it")
    if not run_dir.is_dir():
        raise BouncelabError(run_dir, "run folder not found")
    run_id = check_run_id(run_dir)
    yaml_path = run_dir / RUN_YAML
    if not yaml_path.is_file():
        raise BouncelabError(yaml_path, "run.yaml not found in the run folder")
    data = read_run_yaml(yaml_path)
    check_schema(data, yaml_path)

    for key in ("sample_rate_hz", "drive_frequency_hz", "full_scale_v", "mass_kg"):
        _finite(data, key, yaml_path)
    check_extension_keys(data, yaml_path)
    recording_path = resolve_recording(run_dir, data["recording"], yaml_path)
    audio = recording_path.suffix.lower() in AUDIO_SUFFIXES
    channels = check_channels(data["channels"], audio, yaml_path)
    steps = check_gamma_steps(data.get("gamma_steps", []), yaml_path)
    return Run(
        run_id=run_id,
        path=run_dir,
        kind=data["kind"],
        recording_path=recording_path,
        sample_rate_hz=float(data["sample_rate_hz"]),
        channels=channels,
        full_scale_v=float(data.get("full_scale_v", DEFAULT_FULL_SCALE_V)),
        contact_level=data.get("contact_level", DEFAULT_CONTACT_LEVEL),
        mass_kg=_finite(data, "mass_kg", yaml_path),
        drive_frequency_hz=_finite(data, "drive_frequency_hz", yaml_path),
        gamma_steps=steps,
        settle_cycles=int(data.get("settle_cycles", DEFAULT_SETTLE_CYCLES)),
        drop_height_m=_finite(data, "drop_height_m", yaml_path),
        release_t_s=_finite(data, "release_t_s", yaml_path),
        accel_v_per_g=_finite(data, "accel_v_per_g", yaml_path),
        source=data.get("source"),
        description=data.get("description"),
        extra={k: v for k, v in data.items() if k not in KNOWN_KEYS},
        extra_channels={k: v for k, v in data["channels"].items() if k not in ROLES},
    )


def discover_runs(raw_dir: str | Path) -> list[Path]:
    """Run folders under ``raw_dir``: immediate subfolders holding a ``run.yaml``, by name.

    Hidden folders (name starting with ``.``) are skipped; a folder with a name outside
    the contract's pattern is still listed, so that validating it reports the problem.
    """
    raw_dir = Path(raw_dir)
    if not raw_dir.is_dir():
        raise BouncelabError(raw_dir, "raw data folder not found")
    return sorted(
        (p for p in raw_dir.iterdir() if not p.name.startswith(".") and (p / RUN_YAML).is_file()),
        key=lambda p: p.name,
    )
