"""A cached compiled function follows a change in the modules it calls into (afo_mj.numba_cache).

A throwaway package in a temporary directory: ``a.f`` (njit), ``b.g_plain`` (plain
``cache=True``) and ``b.g`` (``cached_njit(depends_on=(a,))``) returning ``a.f()``, and in
``c`` two cached functions declared on ``b`` (so on ``a`` too, which ``b`` imports):
``h_over_plain`` calls ``b.g_plain``, ``h`` calls ``b.g``. Each run is a fresh process that
prints the values and the dispatchers' cache hits and misses. The reference is the source:
after ``a.f`` is edited to return another value, a fresh process must print that value.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

from afo_mj.gait import (control_law, controller_loop, native_step, reflex_controller,
                         reflex_law, walk_loop)
from afo_mj.human import metabolics, muscle
from afo_mj.numba_cache import DependentFunctionCache

REPO = Path(__file__).resolve().parents[1]

A_SRC = "import numba\n\n\n@numba.njit\ndef f():\n    return {value}\n"
B_SRC = textwrap.dedent("""\
    import numba

    import pkg.a as a
    from afo_mj.numba_cache import cached_njit


    @numba.njit(cache=True)
    def g_plain():
        return a.f()


    @cached_njit(depends_on=(a,))
    def g():
        return a.f()
    """)
C_SRC = textwrap.dedent("""\
    import pkg.b as b
    from afo_mj.numba_cache import cached_njit


    @cached_njit(depends_on=(b,))
    def h_over_plain():
        return b.g_plain()


    @cached_njit(depends_on=(b,))
    def h():
        return b.g()
    """)
RUN_SRC = textwrap.dedent("""\
    import json
    import pkg.b as b
    import pkg.c as c

    out = {}
    for name, fn in (("g_plain", b.g_plain), ("g", b.g), ("h_over_plain", c.h_over_plain),
                     ("h", c.h)):
        value = fn()
        st = fn.stats
        out[name] = [value, sum(st.cache_hits.values()), sum(st.cache_misses.values())]
    print(json.dumps(out))
    """)


def _run(root: Path) -> dict:
    env = dict(os.environ)
    env.update(PYTHONPATH=os.pathsep.join([str(root), str(REPO)]),
               NUMBA_CACHE_DIR=str(root / "numba_cache"),
               # Python's own .pyc check (mtime in seconds, size) would miss an edit of the
               # same size within a second
               PYTHONDONTWRITEBYTECODE="1")
    res = subprocess.run([sys.executable, str(root / "run.py")], env=env, capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout.strip().splitlines()[-1])


def test_a_declared_dependency_invalidates_the_cache_and_an_unchanged_one_hits(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text(A_SRC.format(value=1.0))
    (pkg / "b.py").write_text(B_SRC)
    (pkg / "c.py").write_text(C_SRC)
    (tmp_path / "run.py").write_text(RUN_SRC)

    first = _run(tmp_path)
    assert {k: v[0] for k, v in first.items()} == {
        "g_plain": 1.0, "g": 1.0, "h_over_plain": 1.0, "h": 1.0}
    assert all(v[2] == 1 for v in first.values()), first          # compiled, then saved

    again = _run(tmp_path)                                           # nothing changed
    assert again == {k: [v[0], 1, 0] for k, v in first.items()}     # loaded, no compile

    (pkg / "a.py").write_text(A_SRC.format(value=2.0))              # b.py, c.py untouched
    after = _run(tmp_path)
    # numba's own cache (b.g_plain) is keyed on b.py alone: it still runs the old a.f
    assert after["g_plain"] == [1.0, 1, 0]
    # declared on a: recompiled, the new value
    assert after["g"] == [2.0, 0, 1]
    assert after["h"] == [2.0, 0, 1]
    # declared on b (and so a), but calling a function cached on b.py alone: recompiled, yet
    # built on g_plain's stale code; why a callee needs its own declaration too
    assert after["h_over_plain"] == [1.0, 0, 1]

    # and the new entries are hits in the next process
    assert _run(tmp_path) == {k: [v[0], 1, 0] for k, v in after.items()}


def _covered(dispatcher) -> set[str]:
    cache = dispatcher._cache
    assert isinstance(cache, DependentFunctionCache), cache
    return {m.__name__ for m in cache.modules}


def test_the_compiled_walk_loops_and_the_reflex_law_declare_what_they_call():
    assert {control_law.__name__, native_step.__name__} <= _covered(walk_loop.walk_steps)
    assert {walk_loop.__name__, native_step.__name__} <= _covered(
        controller_loop.controller_steps)
    # the reflex controller's compiled step (a cfunc) is cached with the law it calls
    cf = reflex_controller._reflex_cstep.compile()
    assert isinstance(cf._cache, DependentFunctionCache)
    assert {reflex_law.__name__, muscle.__name__, metabolics.__name__,
            controller_loop.__name__} <= {m.__name__ for m in cf._cache.modules}
    assert {muscle.__name__, metabolics.__name__} <= _covered(reflex_law.reflex_step)
