"""No package of the product (analysis, campaign, drivers) holds a module-level cache.

Each module's syntax tree is scanned for state kept between calls: a module-level name
bound to a mutable container (a dict, list or set display or comprehension, or a call of
dict, list, set, defaultdict, ...) that the module's code changes (item or attribute
assignment or deletion, ``.clear()``, ``.update()``, ``.append()``, ``.setdefault()``,
``.pop()``, ...), any ``global`` statement, and any function decorated with
``functools.cache``/``lru_cache``. Constant tables (column lists, unit maps) are not
changed and pass. What an identification computes once (J, the pose groups) lives on
the problem object (:class:`analysis.identification.problem.IdentificationProblem`) or
is passed; what a robot model computes once (its chain's axis-aligned frames) is an
attribute of the model (:attr:`analysis.model.robot_model.Chain.normal`).

:data:`NOT_CACHES` lists the module-level state that is not a cache: registries of the
processes a server started, which its exit handlers must find.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

import analysis
import analysis.identification as package

ROOT = Path(package.__file__).parent
#: the product's packages (the repository's root holds them side by side)
PACKAGES = ("analysis", "campaign", "drivers")
#: "path:name" of module-level state that is not a cache (the processes a server started
#: now, reaped or interrupted by its exit handlers)
NOT_CACHES = {"campaign/web/acquire_api.py:_children", "campaign/web/job_process.py:LIVE"}
MUTABLE_CALLS = {"dict", "list", "set", "bytearray", "defaultdict", "OrderedDict", "deque",
                 "Counter", "WeakValueDictionary", "WeakKeyDictionary", "ChainMap"}
MUTATORS = {"clear", "update", "append", "extend", "insert", "setdefault", "pop",
            "popitem", "add", "discard", "remove", "appendleft", "__setitem__"}
CACHE_DECORATORS = {"cache", "lru_cache"}


def _call_name(node: ast.AST) -> str | None:
    if isinstance(node, ast.Call):
        f = node.func
        return f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) \
            else None
    return None


def _mutable(value: ast.AST) -> bool:
    if isinstance(value, ast.Dict | ast.List | ast.Set | ast.DictComp | ast.ListComp
                  | ast.SetComp):
        return True
    return _call_name(value) in MUTABLE_CALLS


def _containers(tree: ast.Module) -> dict[str, int]:
    """Module-level names bound to a mutable container: name -> line."""
    out = {}
    for node in tree.body:
        targets, value = [], None
        if isinstance(node, ast.Assign):
            targets, value = node.targets, node.value
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            targets, value = [node.target], node.value
        if value is not None and _mutable(value):
            out.update({t.id: node.lineno for t in targets if isinstance(t, ast.Name)})
    return out


def _changed(tree: ast.Module, names: set[str]) -> set[str]:
    """The ``names`` the module's code changes in place."""
    hit = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Subscript | ast.Attribute) and isinstance(
                node.ctx, ast.Store | ast.Del) and isinstance(node.value, ast.Name):
            hit.add(node.value.id)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and node.func.attr in MUTATORS and isinstance(node.func.value, ast.Name):
            hit.add(node.func.value.id)
        elif isinstance(node, ast.AugAssign) and isinstance(node.target, ast.Name):
            hit.add(node.target.id)
    return hit & names


def module_level_state(source: str) -> list[tuple[int, str]]:
    """(line, what) of each module-level cache in ``source``."""
    tree = ast.parse(source)
    containers = _containers(tree)
    found = [(containers[n], n) for n in sorted(_changed(tree, set(containers)))]
    for node in ast.walk(tree):
        if isinstance(node, ast.Global):
            found.append((node.lineno, "global " + ", ".join(node.names)))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            for d in node.decorator_list:
                name = d.id if isinstance(d, ast.Name) else d.attr if isinstance(
                    d, ast.Attribute) else _call_name(d)
                if name in CACHE_DECORATORS:
                    found.append((node.lineno, f"@{name} {node.name}"))
    return sorted(found)


def test_the_scan_finds_caches():
    src = ("_J_CACHE: dict = {}\n_LAST = dict()\nROWS = [1, 2]\nCOLS = ['a']\nN = 0\n"
           "import functools\n@functools.lru_cache(maxsize=None)\ndef f():\n    pass\n"
           "def g(q):\n    _J_CACHE.clear()\n    _LAST['k'] = q\n    ROWS.append(3)\n"
           "    local = {}\n    local['x'] = 1\n    return COLS\n"
           "def h():\n    global N\n    N += 1\n")
    assert [w for _, w in module_level_state(src)] == [
        "_J_CACHE", "_LAST", "ROWS", "@lru_cache f", "global N"]


def test_analysis_identification_has_no_module_level_cache():
    files = sorted(ROOT.rglob("*.py"))
    assert len(files) > 20
    found = [f"{p.relative_to(ROOT.parents[1])}:{line}: {what}"
             for p in files for line, what in module_level_state(p.read_text())]
    assert not found, "module-level cache (pass it or attach it to the problem " \
        "object):\n" + "\n".join(found)


def test_no_package_has_a_module_level_cache():
    repo = Path(analysis.__file__).parents[1]
    files = [p for pkg in PACKAGES for p in sorted((repo / pkg).rglob("*.py"))]
    assert len(files) > 200
    assert any(p.match("analysis/model/kinematics.py") for p in files)
    found, excused = [], set()
    for p in files:
        rel = p.relative_to(repo).as_posix()
        for line, what in module_level_state(p.read_text()):
            if f"{rel}:{what}" in NOT_CACHES:
                excused.add(f"{rel}:{what}")
            else:
                found.append(f"{rel}:{line}: {what}")
    assert not found, "module-level cache (pass it or attach it to the object it " \
        "belongs to):\n" + "\n".join(found)
    assert excused == NOT_CACHES  # an entry whose state is gone leaves the list


def test_the_model_kinematics_frames_belong_to_the_chain(kr240):
    from dataclasses import replace

    from analysis.model.kinematics import jacobian

    chain = kr240.chain
    assert chain.normal is chain.normal  # made once per chain
    q = np.array([[0.1, -1.2, 1.4, 0.3, 0.7, -0.2]])
    J = jacobian(kr240, q)
    # a new chain (the tool moved 0.1 m along the flange's z) gets frames of its own, and
    # its Jacobian changes only through the moved tip: J's rotational rows are unchanged
    tip = chain.tip.copy()
    tip[:3, 3] += tip[:3, 2] * 0.1
    moved = replace(kr240, chain=replace(chain, tip=tip))
    assert moved.chain.normal is not chain.normal
    Jm = jacobian(moved, q)
    np.testing.assert_allclose(Jm[..., 3:, :], J[..., 3:, :], atol=1e-15)
    assert np.max(np.abs(Jm[..., :3, :] - J[..., :3, :])) > 1e-3
