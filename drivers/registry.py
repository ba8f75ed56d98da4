"""Kinds chosen by a string, the way python-can maps interface names to bus classes.

A `Registry` maps each kind's name to where its implementation lives ("package.module:factory", imported
only when that kind is opened) and a one-line description. A spec is "name" or "name:ARGUMENT"
(`d415:SERIAL`, `replay:PATH`): `open(spec, ...)` calls `factory(argument, ...)`. CLI choices, help texts and
"unknown camera ...: choose one of ..." messages all come from the registry.

Other packages add kinds without touching this one: a module listed under the entry-point group
`axisloop.plugins` is imported before a registry is first read, and registers its kinds (the simulator's
`sim` camera and `sim`/`sim-can` arms register this way from sim_fallback).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Generic, TypeVar

T = TypeVar("T")
PLUGIN_GROUP = "axisloop.plugins"
_plugins_loaded = False


@dataclass(frozen=True)
class Entry:
    """One kind: `target` "module:attribute" names its factory; `argument` is how its argument is written
    (":PATH" required, "[:SERIAL]" optional, None for none); `simulated` kinds live in a simulated world;
    `hardware` kinds drive or read a physical device. Capabilities: `bus` "module:attribute" names a factory of
    the kind's bare bus with no device on top (arms talking to their motors over one: `bus(robot)` returns the
    bus and the simulated motors behind it, or None on hardware); `stream_options` are the stream settings its
    factory takes from the command line (a camera's width, height, fps); `needs` names what the kind needs that
    others of its registry do not (a segmenter's "labels": the simulator's labels or a recording's stored masks;
    "box": the object's box on the first frame; "weights": model weights on this machine). `factory_options` are
    keyword arguments its factory is always called with (kinds sharing one factory: the RealSense models)."""

    name: str
    target: str
    description: str
    argument: str | None = None
    simulated: bool = False
    hardware: bool = False
    bus: str | None = None
    stream_options: tuple[str, ...] = ()
    needs: tuple[str, ...] = ()
    factory_options: tuple[tuple[str, object], ...] = ()

    @property
    def usage(self) -> str:
        """How a user writes it: `d415[:SERIAL]`, `replay:PATH`, `sim`."""
        return self.name + (self.argument or "")

    @property
    def needs_argument(self) -> bool:
        return self.argument is not None and not self.argument.startswith("[")

    @property
    def live(self) -> bool:
        """A device acting or sensing now (simulated or physical), not a recording or a stand-in."""
        return self.simulated or self.hardware

    def load(self) -> Callable[..., object]:
        return _load(self.target)

    def load_bus(self) -> Callable[..., object]:
        """The factory of the kind's bare bus; ValueError when it has none (check `bus` first)."""
        if self.bus is None:
            raise ValueError(f"{self.name!r} has no bus of its own")
        return _load(self.bus)


def _load(target: str) -> Callable[..., object]:
    """The attribute "module:attribute" names (the module imported now)."""
    module, _, attribute = target.partition(":")
    return getattr(importlib.import_module(module), attribute)


class Registry(Generic[T]):
    """The kinds of one thing (camera, arm, segmenter, estimator); `error` is raised for an unknown spec."""

    def __init__(self, kind: str, error: type[Exception]) -> None:
        self.kind = kind
        self.error = error
        self._entries: dict[str, Entry] = {}

    def register(self, name: str, target: str, description: str, argument: str | None = None,
                 simulated: bool = False, hardware: bool = False, bus: str | None = None,
                 stream_options: tuple[str, ...] = (), needs: tuple[str, ...] = (),
                 factory_options: dict[str, object] | None = None) -> None:
        """Add (or replace) kind `name`, built by the factory at `target` ("module:attribute"); the other
        arguments are the `Entry` fields."""
        if ":" in name or not name:
            raise ValueError(f"{self.kind} name {name!r} must be non-empty and contain no ':'")
        self._entries[name] = Entry(name, target, description, argument, simulated, hardware, bus,
                                    tuple(stream_options), tuple(needs), tuple((factory_options or {}).items()))

    def entries(self) -> list[Entry]:
        _load_plugins()
        return list(self._entries.values())

    def names(self) -> list[str]:
        return [e.name for e in self.entries()]

    def help(self) -> str:
        """One line for --help: every kind with its description."""
        return "; ".join(f"{e.usage}: {e.description}" for e in self.entries())

    def entry(self, spec: str) -> tuple[Entry, str]:
        """The entry named by `spec` and its argument ("" when none). Raises `error` naming the choices."""
        name, sep, argument = str(spec).partition(":")
        _load_plugins()
        entry = self._entries.get(name)
        if entry is None:
            raise self.error(f"unknown {self.kind} {spec!r}: choose one of "
                             f"{', '.join(e.usage for e in self._entries.values())}")
        if entry.argument is None and sep:
            raise self.error(f"{self.kind} {name!r} takes no ':{argument}': write just {name}")
        if entry.needs_argument and not argument:
            raise self.error(f"{self.kind} {name!r} needs an argument: write {entry.usage}")
        return entry, argument

    def open(self, spec: str, *args: object, **kwargs: object) -> T:
        """Build the kind named by `spec`: its factory called as factory(argument, *args, **factory_options,
        **kwargs)."""
        entry, argument = self.entry(spec)
        return entry.load()(argument, *args, **dict(entry.factory_options), **kwargs)  # type: ignore[return-value]


def _load_plugins() -> None:
    """Import every module of the `axisloop.plugins` entry-point group once (they register their kinds)."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for point in entry_points(group=PLUGIN_GROUP):
        point.load()
