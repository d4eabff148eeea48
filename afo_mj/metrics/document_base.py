"""The machinery shared by the typed result documents (:mod:`afo_mj.metrics.documents`,
:mod:`afo_mj.calibration.report_document`): frozen dataclasses whose fields carry, in their
metadata, the JSON key's kind, its unit and what it means.

A document class sets ``FORMAT`` (the ``"format"`` tag of its JSON; None for a block that is
only ever embedded in another document) and declares its fields with :func:`entry`. Then

* ``doc.to_json()`` is the JSON-able dict (``{"format": FORMAT, ...}``), keys in field order;
  a field declared ``omit_none`` is left out when it is None (the key is absent rather than
  null in the files written today);
* ``Cls.from_json(data)`` checks the format tag, that every required key is there and no
  unknown one, and each value's kind, raising :class:`DocumentError` that names the document,
  the key and what is allowed.

Numbers are kept as they come (no float() conversion), so that ``to_json()`` of a document
read with ``from_json`` gives back the same JSON value for value.
"""

from __future__ import annotations

import dataclasses
import numbers
from typing import Any, ClassVar, Mapping

__all__ = ["DocumentError", "Document", "entry", "schema_rows"]


class DocumentError(ValueError):
    """A JSON document does not have the shape its class declares (format tag, keys, kinds)."""


#: Value kinds of :func:`entry` (a document class may also be given: a nested document).
KINDS = {
    "number": "number (JSON number; null not allowed)",
    "number?": "number or null",
    "int": "integer",
    "int?": "integer or null",
    "bool": "true/false",
    "bool?": "true/false or null",
    "str": "string",
    "str?": "string or null",
    "object": "JSON object (free-form, described in the field's text)",
    "object?": "JSON object or null",
    "list": "JSON list",
    "list?": "JSON list or null",
    "any": "any JSON value",
}


def entry(kind, doc: str, unit: str = "", omit_none: bool = False, *, map_of=None,
          list_of=None, tagged: bool = True, nullable: bool = False,
          default=dataclasses.MISSING):
    """A document field: ``kind`` (a key of :data:`KINDS`, or a :class:`Document` subclass:
    a nested document), ``doc`` what it means, ``unit`` its SI unit (empty for none).
    ``omit_none``: the key is absent when the value is None; ``nullable``: a nested document
    or ``map_of`` value may be null. ``map_of``: a :class:`Document` subclass: the value is a JSON
    object ``{name: that document or null}``. ``list_of``: a :class:`Document` subclass: the
    value is a JSON list of that document (kept as a tuple). ``tagged``: a nested document
    carries its own ``"format"`` key."""
    meta = {"kind": kind, "doc": doc, "unit": unit, "omit_none": omit_none,
            "map_of": map_of, "list_of": list_of, "tagged": tagged, "nullable": nullable}
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _is_number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


_CHECKS = {
    "number": _is_number, "int": lambda v: isinstance(v, numbers.Integral)
    and not isinstance(v, bool), "bool": lambda v: isinstance(v, bool),
    "str": lambda v: isinstance(v, str), "object": lambda v: isinstance(v, Mapping),
    "list": lambda v: isinstance(v, (list, tuple)), "any": lambda v: True,
}


def _plain(v):
    """A JSON-able copy of a free-form value (mappings and sequences copied)."""
    if isinstance(v, Mapping):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, Document):
        return v.to_json()
    return v


def _freeze(v):
    """A read-only-ish copy of a free-form JSON value for a frozen document (plain dicts
    and tuples; the document's ``to_json`` hands out fresh lists)."""
    if isinstance(v, Mapping):
        return {k: _freeze(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return tuple(_freeze(x) for x in v)
    return v


class Document:
    """Base of the document dataclasses (module docstring)."""

    FORMAT: ClassVar[str | None] = None
    #: What the document is, for the schema page.
    TITLE: ClassVar[str] = ""

    # ------------------------------------------------------------------ to JSON
    def to_json(self) -> dict:
        """The JSON-able dict of this document, ``"format"`` first (when it has one)."""
        out = {"format": self.FORMAT} if self.FORMAT else {}
        out.update(self._body())
        return out

    def to_block(self) -> dict:
        """The JSON-able dict without the format tag: the document embedded in another."""
        return self._body()

    def _body(self) -> dict:
        out = {}
        for f in dataclasses.fields(self):
            m = f.metadata
            if "kind" not in m:
                continue
            v = getattr(self, f.name)
            if v is None and m["omit_none"]:
                continue
            out[f.name] = self._value_json(v, m)
        return out

    @staticmethod
    def _value_json(v, m):
        if v is None:
            return None
        if m["map_of"] is not None:
            return {k: (None if x is None else _nested_json(x, m["tagged"]))
                    for k, x in v.items()}
        if m.get("list_of") is not None:
            return [_nested_json(x, m["tagged"]) for x in v]
        if isinstance(m["kind"], type):
            return _nested_json(v, m["tagged"])
        return _plain(v)

    # ------------------------------------------------------------------ from JSON
    @classmethod
    def from_json(cls, data, where: str | None = None):
        """The document of ``data`` (a JSON-decoded dict); raises :class:`DocumentError`
        naming the key for a wrong format tag, a missing or unknown key or a value of the
        wrong kind."""
        where = where or cls.__name__
        if not isinstance(data, Mapping):
            raise DocumentError(f"{where}: a {type(data).__name__}; allowed: a JSON object")
        if cls.FORMAT is not None:
            got = data.get("format", "<absent>")
            if got != cls.FORMAT:
                raise DocumentError(f"{where}: format = {got!r}; allowed: {cls.FORMAT!r}")
            data = {k: v for k, v in data.items() if k != "format"}
        return cls._from_body(data, where)

    @classmethod
    def _fields(cls):
        return [f for f in dataclasses.fields(cls) if "kind" in f.metadata]

    @classmethod
    def _check_keys(cls, data: Mapping, where: str, keys=None, required=None) -> None:
        fields = cls._fields()
        keys = [f.name for f in fields] if keys is None else list(keys)
        if required is None:
            required = [f.name for f in fields if not f.metadata["omit_none"]]
        missing = [k for k in required if k not in data]
        unknown = [k for k in data if k not in keys]
        if missing:
            raise DocumentError(f"{where}: missing key(s) {', '.join(map(repr, missing))}; "
                                f"required: {', '.join(required)}")
        if unknown:
            raise DocumentError(f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; "
                                f"allowed: {', '.join(keys)}")

    @classmethod
    def _from_body(cls, data: Mapping, where: str):
        cls._check_keys(data, where)
        kw = {f.name: cls._value_from(data.get(f.name), f.metadata, f"{where}.{f.name}")
              for f in cls._fields()}
        return cls(**kw)

    @staticmethod
    def _value_from(v, m, where: str):
        kind = m["kind"]
        if m["map_of"] is not None:
            if v is None and (m["omit_none"] or m["nullable"]):
                return None
            if not isinstance(v, Mapping):
                raise DocumentError(f"{where} = {v!r}; allowed: a JSON object of "
                                    f"{m['map_of'].__name__} (or null)")
            return {k: (None if x is None else _nested_from(m["map_of"], x, m["tagged"],
                                                             f"{where}.{k}"))
                    for k, x in v.items()}
        if m.get("list_of") is not None:
            if v is None and (m["omit_none"] or m["nullable"]):
                return None
            if not isinstance(v, (list, tuple)):
                raise DocumentError(f"{where} = {v!r}; allowed: a JSON list of "
                                    f"{m['list_of'].__name__}")
            return tuple(_nested_from(m["list_of"], x, m["tagged"], f"{where}[{i}]")
                         for i, x in enumerate(v))
        if isinstance(kind, type):
            if v is None:
                if m["omit_none"] or m["nullable"]:
                    return None
                raise DocumentError(f"{where} is null; allowed: a {kind.__name__} object")
            return _nested_from(kind, v, m["tagged"], where)
        nullable = kind.endswith("?") or m["omit_none"]
        base = kind.rstrip("?")
        if v is None:
            if nullable:
                return None
            raise DocumentError(f"{where} is null; allowed: {KINDS[kind]}")
        if not _CHECKS[base](v):
            raise DocumentError(f"{where} = {v!r}; allowed: {KINDS[kind]}")
        return _freeze(v) if base in ("object", "list", "any") else v


def _nested_json(v, tagged: bool):
    return v.to_json() if tagged else v._body()


def _nested_from(cls, v, tagged: bool, where: str):
    if tagged:
        return cls.from_json(v, where)
    if not isinstance(v, Mapping):
        raise DocumentError(f"{where}: a {type(v).__name__}; allowed: a JSON object")
    return cls._from_body(v, where)


def schema_rows(cls) -> list[tuple[str, str, str, str]]:
    """``(key, kind, unit, meaning)`` of each field of document class ``cls`` (for the
    schema page)."""
    rows = []
    for f in dataclasses.fields(cls):
        m = f.metadata
        if "kind" not in m:
            continue
        kind = m["kind"]
        if m["map_of"] is not None:
            k = f"object of {m['map_of'].__name__}"
        elif m.get("list_of") is not None:
            k = f"list of {m['list_of'].__name__}"
        elif isinstance(kind, type):
            k = kind.__name__
        else:
            k = KINDS[kind].split(" (")[0]
        if m["omit_none"]:
            k += " (absent when none)"
        elif m["nullable"]:
            k += " or null"
        rows.append((f.name, k, m["unit"], m["doc"]))
    return rows


def as_document_value(v: Any) -> Any:
    """Free-form JSON value ``v`` as stored in a document (see :func:`_freeze`)."""
    return _freeze(v)
