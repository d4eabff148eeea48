"""numba's on-disk cache, invalidated by a change in any project source a function depends on.

``numba.njit(cache=True)`` keys a function's cache on its *own* source file only
(``numba.core.caching``: the index holds a stamp of the defining file — its content hash in
numba 0.68, its mtime and size before — and nothing of the files of the functions it calls).
A compiled function that calls a function of another module carries that callee's machine code
in its own cache entry, so an edit of the callee's module (or a ``git checkout`` or upgrade
that leaves the caller's file untouched) leaves the caller silently running the old callee.

:func:`cached_njit` (a decorator) and :func:`declare_dependencies` (for a function already
decorated with ``cache=True``) give a function a cache whose stamp is the pair (numba's stamp
of the defining file, a SHA-256 of the declared modules' sources): numba's cache machinery and
locators (``$NUMBA_CACHE_DIR``, ``__pycache__``, the user-wide directory), files of its own
(``<module>.<function>-<line>-deps.py311.nbi``), and an index written under other sources is
not loaded. The declared modules are closed over their own imports from the same top-level
package (a module, or an object such as a function, a numba dispatcher or intrinsic defined in
one, held in a declared module's namespace): declaring ``afo_mj.gait.reflex_law`` also covers
``afo_mj.human.muscle`` and ``afo_mj.human.metabolics``, which it imports. The closure
over-approximates (a module imported for a Python-only helper counts too): a change there
recompiles once, never the other way round.

A callee that is itself cached on its own file (``cache=True``) can still serve stale code to a
caller being recompiled: declare the callee's dependencies too (``declare_dependencies``, or
:func:`declare_module_dependencies` for every cached function of a module).

The hashes are taken once, when the cache is made (at import: a few source files, well under a
millisecond each); the warm path, a cache hit, compares two stamps as numba does.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import sys
import types
from collections.abc import Iterable
from pathlib import Path

import numba
from numba.core.caching import CompileResultCacheImpl, FunctionCache, _CacheLocator

__all__ = ["cached_njit", "cached_cfunc", "LazyCFunc", "declare_dependencies",
           "declare_module_dependencies",
           "dependency_modules", "dependency_digest", "DependentFunctionCache"]


def _top(name: str) -> str:
    return name.partition(".")[0]


def _as_module(dep) -> types.ModuleType:
    if isinstance(dep, types.ModuleType):
        return dep
    if isinstance(dep, str):
        return importlib.import_module(dep)
    raise TypeError(f"depends_on: {dep!r} is a {type(dep).__name__}; allowed: a module or a "
                    "module's dotted name")


def dependency_modules(roots: Iterable, package: str) -> tuple[types.ModuleType, ...]:
    """The modules ``roots`` (modules or dotted names) and, transitively, every module of the
    top-level package ``package`` that one of them imports (a module object in its namespace,
    or an object whose ``__module__`` is one), sorted by name."""
    found: dict[str, types.ModuleType] = {}
    todo = [_as_module(r) for r in roots]
    while todo:
        mod = todo.pop()
        if mod.__name__ in found:
            continue
        found[mod.__name__] = mod
        for value in list(vars(mod).values()):
            if isinstance(value, types.ModuleType):
                name = value.__name__
            else:
                name = getattr(value, "__module__", None)
                if not isinstance(name, str):
                    continue
            if _top(name) == package and name not in found and name in sys.modules:
                todo.append(sys.modules[name])
    return tuple(found[k] for k in sorted(found))


def dependency_digest(modules: Iterable[types.ModuleType]) -> str:
    """SHA-256 over the modules' names and source bytes (a module with no source file, e.g. a
    namespace package, contributes its name only)."""
    h = hashlib.sha256()
    for mod in modules:
        h.update(mod.__name__.encode() + b"\0")
        path = getattr(mod, "__file__", None)
        if path:
            h.update(Path(path).read_bytes())
        h.update(b"\0")
    return h.hexdigest()


class _DependentLocator(_CacheLocator):
    """numba's locator for the function (the first of ``CacheImpl._locator_classes`` that
    accepts it), with a source stamp extended by the dependencies' digest."""

    def __init__(self, base: _CacheLocator, digest: str):
        self._base = base
        self._digest = digest

    def ensure_cache_path(self):
        self._base.ensure_cache_path()

    def get_cache_path(self):
        return self._base.get_cache_path()

    def get_source_stamp(self):
        return (self._base.get_source_stamp(), "afo_mj.numba_cache", self._digest)

    def get_disambiguator(self):
        # its own index and data files: a process that loads the defining module alone (numba's
        # plain cache) and one that declares its dependencies do not overwrite each other's
        return self._base.get_disambiguator() + "-deps"


class _DependentCacheImpl(CompileResultCacheImpl):
    def __init__(self, py_func, digest: str):
        super().__init__(py_func)
        self._locator = _DependentLocator(self._locator, digest)


class DependentFunctionCache(FunctionCache):
    """numba's ``FunctionCache`` whose source stamp also covers ``modules`` (see the module
    docstring); ``modules`` and ``digest`` say what it covers."""

    def __init__(self, py_func, modules: tuple[types.ModuleType, ...]):
        self.modules = modules
        self.digest = dependency_digest(modules)
        self._impl_class = functools.partial(_DependentCacheImpl, digest=self.digest)
        super().__init__(py_func)


def declare_dependencies(dispatcher, depends_on: Iterable):
    """Give ``dispatcher`` (a numba ``njit`` function) an on-disk cache that a change in any of
    ``depends_on`` (modules or dotted names, closed over their imports from the function's
    top-level package; its own module is covered by numba) invalidates; returns it. Declaring
    again adds to the modules already declared.

    A dispatcher that has already loaded code from its old cache (keyed on its own file only,
    so possibly stale) drops it: its next call compiles or loads through the new cache. Code it
    compiled in this process is kept (it was compiled from the sources loaded)."""
    if not isinstance(dispatcher, numba.core.dispatcher.Dispatcher):
        raise TypeError(f"declare_dependencies: {dispatcher!r} is a "
                        f"{type(dispatcher).__name__}; allowed: a numba.njit function")
    py_func = dispatcher.py_func
    roots = list(depends_on)
    old = dispatcher._cache
    if isinstance(old, DependentFunctionCache):
        roots.extend(old.modules)
    modules = dependency_modules(roots, _top(py_func.__module__))
    if sum(dispatcher._cache_hits.values()):
        # numba's own Dispatcher.recompile drops its overloads the same way
        dispatcher._make_finalizer()()
        dispatcher._reset_overloads()
        dispatcher._cache_hits.clear()
    dispatcher._cache = DependentFunctionCache(py_func, modules)
    return dispatcher


def cached_njit(*, depends_on: Iterable, **njit_kwargs):
    """``numba.njit(cache=True, **njit_kwargs)`` whose cache a change in any module of
    ``depends_on`` (see :func:`declare_dependencies`) invalidates too."""
    if "cache" in njit_kwargs:
        raise TypeError(f"cached_njit: cache={njit_kwargs['cache']!r} given; allowed: none "
                        "(the function is always cached)")
    depends_on = tuple(depends_on)

    def decorate(py_func):
        return declare_dependencies(numba.njit(**njit_kwargs)(py_func), depends_on)

    return decorate


def declare_module_dependencies(module) -> tuple:
    """Declare, for every numba function that ``module`` (a module or dotted name) defines with
    an on-disk cache, the modules ``module`` imports from its package (closed as in
    :func:`dependency_modules`; the module itself is covered by numba); returns those
    functions. For a module whose cached functions call another module's compiled functions."""
    module = _as_module(module)
    done = []
    for value in list(vars(module).values()):
        if (isinstance(value, numba.core.dispatcher.Dispatcher)
                and value.py_func.__module__ == module.__name__
                and isinstance(value._cache, FunctionCache)):
            done.append(declare_dependencies(value, (module,)))
    return tuple(done)


class LazyCFunc:
    """A ``numba.cfunc`` cached like :func:`cached_njit` (its stamp covers the declared
    modules too), compiled — or loaded from the cache — on first use of :attr:`address` (or
    :meth:`compile`), not at import."""

    def __init__(self, py_func, sig, depends_on: Iterable, options: dict):
        from numba.core import sigutils
        self.py_func, self.sig = py_func, sigutils.normalize_signature(sig)
        self.depends_on, self.options = tuple(depends_on), dict(options)
        self._cfunc = None

    def compile(self):
        """The compiled ``numba`` CFunc (compiled or loaded once per process)."""
        if self._cfunc is None:
            from numba.core.ccallback import CFunc
            cf = CFunc(self.py_func, self.sig, locals={}, options=self.options)
            modules = dependency_modules(self.depends_on, _top(self.py_func.__module__))
            cf._cache = DependentFunctionCache(self.py_func, modules)
            cf.compile()
            self._cfunc = cf
        return self._cfunc

    @property
    def address(self) -> int:
        """The C function's address."""
        return self.compile().address

    @property
    def cache_hits(self) -> int:
        return self.compile().cache_hits


def cached_cfunc(sig, *, depends_on: Iterable, **options):
    """``numba.cfunc(sig, cache=True, **options)`` with the dependent cache of
    :func:`cached_njit`, compiled on first use (:class:`LazyCFunc`)."""
    def decorate(py_func):
        return LazyCFunc(py_func, sig, depends_on, options)

    return decorate
