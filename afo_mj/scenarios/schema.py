"""The declared tables of the scenario files, and the one check of a parsed table against them.

Every TOML table a scenario file may hold (the top level, ``[gait]``, ``[device]``,
``[assistance]``, ``[bench]``, ``[circuit]``, ...) is declared once, as a :class:`Table`: its
keys in order, each a :class:`Key` with its kind of value, range, default, unit and meaning.
The parsers read ranges and defaults from these declarations, and :func:`check_table` refuses
a key the table does not declare, in one format for every table::

    <origin>: unknown key '<table>.<key>' (= <value>) (did you mean '<table>.<closest>'?);
    allowed keys in [<table>]: <key>, <key>, ...

(``unknown key '<key>'`` and ``allowed keys:`` for the top level; the suggestion only when a
declared key is close, :func:`did_you_mean`.) Tables whose keys are the fields of a parameter
dataclass (``[walker]``, ``[controller]``) are declared from those fields when read
(:meth:`Table.of_names`), so the dataclass stays their one declaration.
"""

from __future__ import annotations

import dataclasses
import difflib
from typing import Any, Iterable, Mapping

__all__ = ["Key", "Table", "ScenarioError", "check_table", "did_you_mean", "NO_DEFAULT"]

#: the default of a key that has none (required, or derived from other keys)
NO_DEFAULT: Any = None

#: kinds of value a key holds (documentation; the parsers check values themselves)
KINDS = ("any", "string", "number", "integer", "bool", "list", "table")


class ScenarioError(ValueError):
    """An invalid scenario: names the file, the dotted key, the value and what is allowed."""


def did_you_mean(key: str, allowed, prefix: str = "", suffix: str = "") -> str:
    """`` (did you mean 'prefix' + x + 'suffix'?)`` for the closest ``x`` of ``allowed`` to
    ``key`` (difflib, cutoff 0.6), or ''."""
    near = difflib.get_close_matches(str(key), [str(a) for a in allowed], n=1, cutoff=0.6)
    return f" (did you mean {prefix + near[0] + suffix!r}?)" if near else ""


@dataclasses.dataclass(frozen=True)
class Key:
    """One key of a table: ``kind`` of value (:data:`KINDS`), ``range`` (lo, hi) of a number,
    an integer or a list's items (None: unbounded or checked elsewhere), ``default`` when the
    key is absent (:data:`NO_DEFAULT`: none), ``unit`` of a quantity, ``doc`` its meaning, and
    ``group``: the variant of the table the key belongs to ("" for every variant; e.g. the
    ``[assistance]`` keys of one profile)."""

    name: str
    kind: str = "any"
    range: tuple[float, float] | None = None
    default: Any = NO_DEFAULT
    unit: str = ""
    doc: str = ""
    group: str = ""

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"Key {self.name!r}: kind = {self.kind!r}; allowed: "
                             + ", ".join(KINDS))
        if self.range is not None and not self.range[0] <= self.range[1]:
            raise ValueError(f"Key {self.name!r}: range = {self.range!r}; allowed: lo <= hi")


@dataclasses.dataclass(frozen=True)
class Table:
    """A declared table: ``name`` (dotted, "" for the top level of a file), its keys in the
    order errors list them, and ``note``: what an unknown-key error adds after that list
    (e.g. ``(a bench scenario has no walker or gait)``)."""

    name: str
    keys: tuple[Key, ...]
    note: str = ""

    def __post_init__(self):
        names = [k.name for k in self.keys]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"Table [{self.name}]: keys {dup} declared twice; allowed: once")

    @classmethod
    def of_names(cls, name: str, names: Iterable[str], note: str = "") -> "Table":
        """A table whose keys are only named (e.g. a parameter dataclass's fields, which
        declare their own types and ranges)."""
        return cls(name, tuple(Key(n) for n in names), note)

    @property
    def names(self) -> tuple[str, ...]:
        """The declared key names, in order."""
        return tuple(k.name for k in self.keys)

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def __getitem__(self, name: str) -> Key:
        for k in self.keys:
            if k.name == name:
                return k
        raise KeyError(f"[{self.name}] declares no key {name!r}")

    def default(self, name: str) -> Any:
        """The declared default of key ``name``."""
        return self[name].default

    def group(self, group: str) -> tuple[str, ...]:
        """The names of the keys of one variant of the table (:attr:`Key.group`)."""
        return tuple(k.name for k in self.keys if k.group == group)

    def only(self, *names: str, note: str = "") -> "Table":
        """The same table restricted to ``names`` (in that order): a file kind that accepts
        part of a table another declares (a bench's ``[device]``)."""
        return Table(self.name, tuple(self[n] for n in names), note)

    def dotted(self, name: str) -> str:
        """``table.key`` (``key`` at the top level)."""
        return f"{self.name}.{name}" if self.name else name


def check_table(doc: Mapping, schema: Table, origin: str, table_name: str | None = None,
                error: type[Exception] = ScenarioError) -> None:
    """Refuse the first key of the parsed table ``doc`` that ``schema`` does not declare:
    ``error`` (default :class:`ScenarioError`) naming ``origin``, the dotted key, its value,
    the closest declared key and every declared key (module docstring). ``table_name``
    overrides the schema's name in the message."""
    table = schema.name if table_name is None else table_name
    allowed = schema.names
    prefix = f"{table}." if table else ""
    for k, v in doc.items():
        if k not in allowed:
            where = f" in [{table}]" if table else ""
            note = f" {schema.note}" if schema.note else ""
            raise error(f"{origin}: unknown key {prefix + str(k)!r} (= {v!r})"
                        f"{did_you_mean(k, allowed, prefix)}; allowed keys{where}: "
                        f"{', '.join(allowed)}{note}")
