"""Typed settings that can be dumped to JSON and loaded back (like kiss-icp's).

A settings class is a dataclass whose fields are plain values or other
settings (nested dataclasses, or classes with ``to_dict``/``from_dict``).
:class:`Settings` gives it ``to_dict``, ``from_dict``, ``dump`` and ``load``;
unknown keys and bad values raise :class:`ConfigError` naming the field.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import types
import typing
from typing import Any, Mapping, TypeVar

import numpy as np

from . import strict_json
from .errors import ConfigError, given_path, quoted, quoted_json
from .plain_numbers import is_number, is_whole_number

#: Largest settings file read (radarodom's own are a few KB).
MAX_SETTINGS_BYTES = 1 << 20

S = TypeVar("S", bound="Settings")


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    """*cls*'s resolved type hints, once per class (every settings object built checks them)."""
    return typing.get_type_hints(cls)


def _nested_type(cls: type, name: str) -> type | None:
    """The field's class when it is itself loadable from a dict, else None."""
    hint = _hints(cls).get(name)
    return hint if isinstance(hint, type) and hasattr(hint, "from_dict") else None


def check_field(ok: bool, message: str, name: str) -> None:
    """:class:`ConfigError` naming field *name* with *message* unless *ok*."""
    if not ok:
        raise ConfigError(message, field=name)


def check_choice(value: Any, choices: tuple[str, ...], name: str) -> None:
    """:class:`ConfigError` naming field *name* unless *value* is one of *choices*."""
    if value not in choices:
        raise ConfigError(f"must be one of {', '.join(choices)}, got {value!r}", field=name)


_KINDS = {bool: "a boolean", int: "an integer", float: "a number", str: "a string"}


def _checked(value: Any, hint: Any, name: str, quote=quoted_json) -> Any:
    """*value* if it has the type *hint* asks for (ints accepted as floats), else
    :class:`ConfigError` naming the field, the value spelled by *quote* (JSON's words for a file's
    values, Python's for values given in Python).  Hints other than the plain ones pass."""
    allowed = typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
    if value is None and type(None) in allowed:
        return value
    for kind in allowed:
        if kind is bool and isinstance(value, (bool, np.bool_)):
            return bool(value)
        # numpy's integers and floats count (a value computed in numpy)
        if kind is int and is_whole_number(value):
            return int(value)
        if kind is float and is_number(value):
            try:
                number = float(value)
            except OverflowError:  # an int beyond any float
                number = math.inf
            if not math.isfinite(number):
                raise ConfigError(f"must be a finite number, got {quote(value)}", field=name)
            return number
        if kind is str and isinstance(value, str):
            return value
    plain = [k for k in allowed if k in _KINDS]
    if not plain or len(plain) < len([k for k in allowed if k is not type(None)]):
        return value  # not a plain type (a nested section is checked by its own from_dict)
    none = " or null" if quote is quoted_json else " or None"
    wanted = " or ".join(_KINDS[k] for k in plain) + (none if type(None) in allowed else "")
    raise ConfigError(f"must be {wanted}, got {quote(value)}", field=name)


class Settings:
    """Mixin for dataclasses: JSON round trip with field-level errors.  Each subclass's
    ``__post_init__`` calls :meth:`check_types` first, so that settings built in Python are
    checked as those read from JSON are."""

    #: What the settings are called in messages ("DSP", "estimator", ...).
    _what = "settings"

    def check_types(self) -> None:
        """:class:`ConfigError` naming the first field whose value is not of its declared type
        (a nested section not of its settings class); ints given for numbers become floats."""
        hints = _hints(type(self))
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            if not f.init:
                continue
            value = getattr(self, f.name)
            nested = _nested_type(type(self), f.name)
            if nested is None:
                object.__setattr__(self, f.name, _checked(value, hints.get(f.name), f.name, quoted))
            elif not isinstance(value, nested):
                raise ConfigError(f"must be {nested.__name__} settings ({nested.__name__}.from_dict makes them "
                                  f"from a dict), got {type(value).__name__} {quoted(value)}", field=f.name)

    def to_dict(self) -> dict[str, Any]:
        out = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            if not f.init:
                continue
            value = getattr(self, f.name)
            out[f.name] = value.to_dict() if hasattr(value, "to_dict") else value
        return out

    @classmethod
    def from_dict(cls: type[S], data: Mapping[str, Any], *, prefix: str = "") -> S:
        """Settings from a dict (nested sections as dicts); errors name the field by its
        path (``icp.iterations``)."""
        try:
            return cls._from_dict(data, prefix)
        except ConfigError as exc:
            if prefix and exc.field and not exc.field.startswith(prefix):
                raise exc.located(field=prefix + exc.field)
            unknown = getattr(exc, "unknown", None)
            if not prefix and unknown:  # the whole tree is known here: say where a misplaced key goes
                exc.message = f"unknown {cls._what} setting(s): " + ", ".join(p + _elsewhere(cls, p) for p in unknown)
                raise exc.located()
            raise

    @classmethod
    def _from_dict(cls: type[S], data: Mapping[str, Any], prefix: str) -> S:
        if not isinstance(data, Mapping):
            raise ConfigError(f"{cls._what} settings must be an object, got {type(data).__name__}",
                              field=prefix.rstrip(".") or None)
        known = {f.name for f in dataclasses.fields(cls) if f.init}  # type: ignore[arg-type]
        unknown = set(data) - known
        if any(not isinstance(key, str) for key in unknown):
            raise ConfigError(f"{cls._what} settings are named by strings, got "
                              + ", ".join(quoted(k) for k in unknown if not isinstance(k, str)),
                              field=prefix.rstrip(".") or None)
        if unknown:
            paths = [prefix + k for k in sorted(unknown)]
            error = ConfigError(f"unknown {cls._what} setting(s): " + ", ".join(paths))
            error.unknown = paths  # type: ignore[attr-defined]  # for the top level's hint (from_dict)
            raise error
        values = dict(data)
        hints = _hints(cls)
        for key, value in data.items():
            nested = _nested_type(cls, key)
            if nested is None:
                values[key] = _checked(value, hints.get(key), key)
            elif isinstance(value, Mapping):
                if issubclass(nested, Settings):
                    values[key] = nested.from_dict(value, prefix=f"{prefix}{key}.")
                else:
                    values[key] = _nested_from_dict(cls, nested, value, key)
            elif not isinstance(value, nested):
                raise ConfigError(f"must be an object of {nested.__name__} settings, got {quoted_json(value)}",
                                  field=key)
        try:
            return cls(**values)
        except TypeError as exc:
            raise ConfigError(f"bad {cls._what} settings: {exc}") from None

    def dump(self, path: str | os.PathLike) -> None:
        """These settings as a JSON file at *path* (written over); :class:`ConfigError` naming it
        when it cannot be written."""
        path = given_path(path, ConfigError, "settings file path")
        try:
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(strict_json.dumps(self.to_dict(), indent=2) + "\n")
        except OSError as exc:
            raise ConfigError(f"cannot write {self._what} settings: {exc.strerror or exc}", path=path) from None

    @classmethod
    def load(cls: type[S], path: str | os.PathLike) -> S:
        """Settings from a JSON file of at most :data:`MAX_SETTINGS_BYTES`: standard JSON (no NaN
        or Infinity), nested at most :data:`radarodom.strict_json.MAX_DEPTH` deep."""
        if isinstance(path, bytes):
            path = os.fsdecode(path)
        if not isinstance(path, (str, os.PathLike)) or "\0" in os.fspath(path):
            raise ConfigError(f"expected a settings file path, got {str(path)!r:.60}")
        try:
            with open(path, "rb") as fh:
                raw = fh.read(MAX_SETTINGS_BYTES + 1)
            data = strict_json.loads(raw, max_bytes=MAX_SETTINGS_BYTES)
        except OSError as exc:
            raise ConfigError(f"cannot read {cls._what} settings: {exc.strerror or exc}", path=path) from None
        except ValueError as exc:
            raise ConfigError(f"cannot read {cls._what} settings: {exc}", path=path) from None
        if not isinstance(data, dict):
            raise ConfigError(f"{cls._what} settings must be a JSON object", path=path)
        try:
            return cls.from_dict(data)
        except ConfigError as exc:
            raise exc.located(path=path)


def _setting_paths(cls: type, prefix: str = "") -> list[str]:
    """Every setting's and section's path in *cls*'s tree (``icp``, ``icp.iterations``, ...)."""
    paths = []
    for f in dataclasses.fields(cls):
        if f.init:
            paths.append(prefix + f.name)
            nested = _nested_type(cls, f.name)
            if nested is not None and issubclass(nested, Settings):
                paths += _setting_paths(nested, f"{prefix}{f.name}.")
    return paths


def _elsewhere(root: type, path: str) -> str:
    """" (it is odometry.yaw_noise_rad)" for an unknown *path* whose last name is a setting
    elsewhere in *root*'s tree (a key put in the wrong section), else ""."""
    name = path.rpartition(".")[2]
    found = [p for p in _setting_paths(root) if p.rpartition(".")[2] == name and p != path]
    return f" (it is {' or '.join(found)})" if found else ""


def _nested_from_dict(cls: type, nested: type, value: Mapping[str, Any], key: str) -> Any:
    """A section of another type (a CFAR's parameters) given over the field's default, as a
    nested :class:`Settings` section's keys are over its own (``{"cfar": {"threshold_db": 12}}``
    keeps the rest of the default CFAR); its errors named by their path under *key*
    (``cfar.guard``)."""
    default = next(f.default_factory for f in dataclasses.fields(cls) if f.name == key)  # type: ignore[misc]
    try:
        if default is dataclasses.MISSING:
            return nested.from_dict(value)
        return default().updated(value)
    except ConfigError as exc:
        raise exc.located(field=f"{key}.{exc.field}" if exc.field else key, command=None)
