"""Engine discovery and creation from spec strings.

Engines are found through the entry-point group ``mocap_workbench.engines`` (the
built-ins are registered the same way in pyproject.toml), through :func:`register`, or
named directly as ``"package.module:Class"``.

Spec grammar: ``name`` or ``name:key=value,key=value``; a pipeline joins specs with
``>`` (``lerp>gaussian:sigma_ms=58``): the first stage fills gaps, the next cleans. A
trainable engine also takes ``weights=DIR``: load its trained state from DIR instead of
the committed weights.
"""

from __future__ import annotations

import difflib
import importlib
from importlib.metadata import entry_points

from .engine import Engine, EngineError, Pipeline

ENTRY_POINT_GROUP = "mocap_workbench.engines"
_registered: dict[str, type] = {}


def _entry_points() -> dict:
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available() -> list[str]:
    """Names of every registered engine, sorted."""
    return sorted(set(_entry_points()) | set(_registered))


def register(name: str, cls: type) -> None:
    """Register an engine class at run time (plugins, tests)."""
    _registered[name] = cls


def get(name: str) -> type:
    """The engine class registered under ``name``."""
    if name in _registered:
        return _registered[name]
    eps = _entry_points()
    if name not in eps:
        names = available()
        near = difflib.get_close_matches(name.lower(), names, n=1)
        hint = f"did you mean {near[0]!r}? " if near else ""
        raise EngineError(f"unknown engine {name!r}; {hint}available: {', '.join(names)}")
    try:
        return eps[name].load()
    except Exception as err:  # a broken plugin must not take the whole program down
        raise EngineError(f"engine {name!r} failed to load: {err}") from err


def _import_class(path: str) -> type:
    module, _, cls = path.partition(":")
    try:
        found = getattr(importlib.import_module(module), cls)
    except (ImportError, AttributeError) as err:
        raise EngineError(f"cannot import engine class {path!r}: {err}") from None
    if not (isinstance(found, type) and issubclass(found, Engine) and found is not Pipeline and hasattr(found, "info")):
        raise EngineError(f"{path!r} is no engine class: name a subclass of workbench.engine.Engine with its info")
    return found


def parse_options(text: str) -> dict[str, str]:
    """``"a=1,b=x"`` -> ``{"a": "1", "b": "x"}``; EngineError for an item that is not
    name=value and for a name given twice (which value was meant?)."""
    options: dict[str, str] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        key, eq, value = (part.strip() for part in item.partition("="))
        if not eq or not key:
            raise EngineError(f"engine parameter {item!r} must look like name=value")
        if key in options:
            raise EngineError(f"engine parameter {key!r} given twice ({options[key]} and {value})")
        options[key] = value
    return options


def create(spec: str, *, pretrained: bool = True) -> Engine:
    """Build an engine (or pipeline) from a spec string; trainable engines load their
    committed weights when ``pretrained`` and they have some."""
    if not isinstance(spec, str):
        raise TypeError(f"an engine spec is a string such as 'ebf' or 'lerp>ebf', not a {type(spec).__name__}")
    spec = spec.strip()
    if not spec:
        raise EngineError("empty engine spec")
    if ">" in spec:
        return Pipeline([create(part, pretrained=pretrained) for part in spec.split(">")])
    head, _, rest = spec.partition(":")
    if "." in head:  # package.module:Class[:options]
        cls_name, _, opts = rest.partition(":")
        cls = _import_class(f"{head}:{cls_name}")
    else:
        cls, opts = get(head), rest
    engine = cls.from_options(parse_options(opts))
    return engine.load_pretrained() if pretrained else engine
