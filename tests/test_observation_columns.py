"""Observation columns are read by name (`crossing_env.observation`), never by bare number.

What is flagged, per module of the reader packages (parsed with `ast`, nothing imported):

- An *observation array* is an expression that reads an observation key: ``X[key]`` or ``X.get(key, ...)``
  where ``key`` is one of the keys, spelt as a string literal or as its constant (a name or attribute
  ending in one of the ``*_KEY`` names of `crossing_env.observation`, e.g. ``PEDESTRIANS_KEY`` or
  ``observation.VEHICLES_KEY``; read from that module's source),
  or an attribute named after a key (``view.vehicles``). So is ``np.asarray``/``np.array``/
  ``np.ascontiguousarray``/``np.float64``... of one, a method call on one (``.astype``, ``.reshape``,
  ``.copy``, ...), a subscript of one that does not pick a column (``ped[present]``), and a local name
  assigned from one anywhere in the same function (or module body; nested functions see their parents').
- A subscript of an observation array is flagged when the last element of its index is an integer literal
  (``ped[:, 3]``, ``ego[0]``, ``veh[..., -1]``), a tuple or list of them (``veh[:, (1, 3, 5)]``) or a slice
  with a literal bound (``paths[..., :2]``): the last position is the column. To take a row or a time
  sample, index every axis (``hist[:, -1, :]``) or use a name.

`PENDING` lists modules of other owners not converted yet; they are expected to fail (strict xfail), so
the list must shrink as they are converted.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = (
    "crossing_env",
    "predictors",
    "agents",
    "rollout",
    "crossing_replay",
    "crossing_eval",
    "studies",
    "examples",
    "benchmarks",
)
"""Folders whose modules read observations (missing ones are skipped)."""
LAYOUT = "crossing_env/observation.py"
"""The module that names the keys and columns."""
WRITERS = {LAYOUT}
"""Modules that define the layout (the builder fills the arrays by name, but it also defines the keys)."""
PENDING: set[str] = set()
"""Readers owned elsewhere that still index columns by number (convert, then remove them from here)."""


def _key_constants() -> dict[str, str]:
    """``{constant name: key}`` of the ``*_KEY`` string constants defined by the layout module."""
    tree = ast.parse((REPO / LAYOUT).read_text(encoding="utf-8"))
    found = {}
    for node in tree.body:
        target = node.target if isinstance(node, ast.AnnAssign) else None
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target = node.targets[0]
        value = getattr(node, "value", None)
        if (
            isinstance(target, ast.Name)
            and target.id.endswith("_KEY")
            and isinstance(value, ast.Constant)
            and isinstance(value.value, str)
        ):
            found[target.id] = value.value
    return found


KEYS = _key_constants()
KEY_VALUES = frozenset(KEYS.values())
KEY_CONSTANTS = frozenset(KEYS)
ARRAY_FUNCTIONS = frozenset(
    {"asarray", "array", "ascontiguousarray", "asanyarray", "float64", "float32", "atleast_1d", "atleast_2d"}
)
"""``np.<name>(obs_array, ...)`` is still the observation array."""


def _is_key(node: ast.AST | None) -> bool:
    """A key of the observation dict, as a string literal or as one of the ``*_KEY`` constants."""
    if isinstance(node, ast.Constant):
        return isinstance(node.value, str) and node.value in KEY_VALUES
    if isinstance(node, ast.Name):
        return node.id in KEY_CONSTANTS
    if isinstance(node, ast.Attribute):
        return node.attr in KEY_CONSTANTS
    return False


def _int_literal(node: ast.AST | None) -> bool:
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        node = node.operand
    return isinstance(node, ast.Constant) and type(node.value) is int


def _column_index(index: ast.AST) -> bool:
    """Whether a subscript's index picks columns by number (its last element, see the module docstring)."""
    last = index.elts[-1] if isinstance(index, ast.Tuple) and index.elts else index
    if _int_literal(last):
        return True
    if isinstance(last, (ast.Tuple, ast.List)):
        return bool(last.elts) and all(_int_literal(e) for e in last.elts)
    if isinstance(last, ast.Slice):
        return _int_literal(last.lower) or _int_literal(last.upper)
    return False


SCOPES = (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)


def _scope_nodes(body: list[ast.stmt]) -> Iterator[ast.AST]:
    """Every node of a scope's body; nested functions, lambdas and classes are yielded but not entered."""
    stack: list[ast.AST] = list(reversed(body))
    while stack:
        node = stack.pop()
        yield node
        if not isinstance(node, SCOPES):
            stack.extend(reversed(list(ast.iter_child_nodes(node))))


def _nested_scopes(body: list[ast.stmt]) -> Iterator[ast.AST]:
    """The functions, lambdas and classes directly inside a scope (not inside each other)."""
    return (node for node in _scope_nodes(body) if isinstance(node, SCOPES))


class _Scope:
    """Observation arrays of one function (or module / class body) and the column subscripts on them."""

    def __init__(self, body: list[ast.stmt], inherited: frozenset[str]) -> None:
        self.body = body
        self.names = set(inherited)
        changed = True
        while changed:  # assignments may come in any order (loops): iterate to a fixed point
            changed = False
            for node in _scope_nodes(body):
                for target, value in _assignments(node):
                    if target not in self.names and self.is_array(value):
                        self.names.add(target)
                        changed = True

    def is_array(self, node: ast.AST | None) -> bool:
        """Whether `node` evaluates to an observation array (or a view of one)."""
        if isinstance(node, ast.Name):
            return node.id in self.names
        if isinstance(node, ast.Attribute):
            return node.attr in KEY_VALUES
        if isinstance(node, ast.Subscript):
            if _is_key(node.slice):
                return True
            return self.is_array(node.value) and not _column_index(node.slice)
        if isinstance(node, ast.Call):
            func = node.func
            if isinstance(func, ast.Attribute):
                if func.attr == "get" and node.args and _is_key(node.args[0]):
                    return True
                if func.attr in ARRAY_FUNCTIONS and node.args:
                    return self.is_array(node.args[0])
                return self.is_array(func.value)  # obs_array.astype(...), .reshape(...), .copy()
        if isinstance(node, ast.NamedExpr):
            return self.is_array(node.value)
        return False

    def offences(self) -> Iterator[ast.Subscript]:
        for node in _scope_nodes(self.body):
            if isinstance(node, ast.Subscript) and self.is_array(node.value) and _column_index(node.slice):
                yield node


def _assignments(node: ast.AST) -> Iterator[tuple[str, ast.AST | None]]:
    if isinstance(node, ast.Assign):
        for target in node.targets:
            if isinstance(target, ast.Name):
                yield target.id, node.value
    elif isinstance(node, (ast.AnnAssign, ast.AugAssign, ast.NamedExpr)) and isinstance(
        node.target, ast.Name
    ):
        yield node.target.id, node.value


def column_offences(source: str) -> list[str]:
    """``"line: code"`` of every subscript that indexes observation columns by number in `source`."""
    tree = ast.parse(source)
    found: list[ast.Subscript] = []
    # (body, names seen from it, names its nested functions see: a class body's own are not visible there)
    pending: list[tuple[list[ast.stmt], frozenset[str], bool]] = [(tree.body, frozenset(), False)]
    while pending:
        body, inherited, is_class = pending.pop()
        scope = _Scope(body, inherited)
        found.extend(scope.offences())
        visible = inherited if is_class else frozenset(scope.names)
        for nested in _nested_scopes(body):
            if isinstance(nested, ast.ClassDef):
                pending.append((nested.body, visible, True))
                continue
            params = {arg.arg for arg in ast.walk(nested.args) if isinstance(arg, ast.arg)}
            nested_body = [ast.Expr(nested.body)] if isinstance(nested, ast.Lambda) else nested.body
            pending.append((nested_body, visible - params, False))
    found.sort(key=lambda node: (node.lineno, node.col_offset))
    return [f"{node.lineno}: {ast.unparse(node)}" for node in found]


def _modules() -> list[str]:
    paths = [path for package in PACKAGES for path in sorted((REPO / package).rglob("*.py"))]
    return [path.relative_to(REPO).as_posix() for path in paths if "__pycache__" not in path.parts]


MODULES = _modules()


@pytest.mark.parametrize(
    "module",
    [
        pytest.param(m, marks=pytest.mark.xfail(strict=True, reason="not converted yet"))
        if m in PENDING
        else m
        for m in MODULES
        if m not in WRITERS
    ],
)
def test_no_bare_column_index(module: str) -> None:
    offences = column_offences((REPO / module).read_text(encoding="utf-8"))
    assert not offences, (
        f"{module} indexes observation columns by number (use crossing_env.observation):\n"
        + ("\n".join(offences))
    )


def test_pending_modules_exist() -> None:
    assert PENDING <= set(MODULES), f"PENDING names modules that are gone: {sorted(PENDING - set(MODULES))}"


FLAGGED = [
    'ped = obs["pedestrians"]\nx = ped[:, 1]',
    'x = obs["pedestrians"][..., 3]',
    "x = obs[PEDESTRIANS_KEY][..., 3]",
    "x = obs[observation.VEHICLES_KEY][:, -1]",
    'speed = float(obs["ego"][0])',
    'ego = np.asarray(obs["ego"], dtype=np.float64).reshape(-1, 6)\ns = ego[:, 0]',
    'veh = obs.get("vehicles")\nrows = veh[:, (1, 3, 5)]',
    "paths = obs.get(PREDICTED_PATHS_KEY)\nxy = paths[..., :2]",
    "def f(view):\n    veh = view.vehicles\n    return veh[..., 0] > 0.5",
    "ped = obs[PEDESTRIANS_KEY]\ndef f():\n    return ped[present][:, 7]",
    "for _ in range(3):\n    y = p[..., 2]\n    p = q\nq = obs[PEDESTRIANS_KEY].astype(np.float64)",
    'present = np.asarray(obs["pedestrians"])[:, 0] > 0.5',
]
NOT_FLAGGED = [
    'x = obs["pedestrians"][..., PedestrianColumn.VX]',
    'hist = obs["pedestrian_history"][present]\nlast = hist[:, -1, :]',
    'k = obs["pedestrians"].shape[0]',
    "arr = np.zeros((3, 2))\nx = arr[:, 0]",
    'def f(obs):\n    ped = obs["pedestrians"]\ndef g(ped):\n    return ped[:, 1]',
    'row = table["pedestrian"][:, 1]',
    'present = obs["pedestrians"][:, PedestrianColumn.PRESENCE] > 0.5\nx = present[0, :]',
    "class A:\n    veh = obs[VEHICLES_KEY]\n    def f(self):\n        return veh[:, 1]",
    'ped = obs["pedestrians"]\ndef f(ped):\n    return ped[:, 1]',
    'ped = obs["pedestrians"]\ng = lambda ped: ped[:, 1]',
]


@pytest.mark.parametrize("source", FLAGGED)
def test_checker_flags(source: str) -> None:
    assert column_offences(source), source


@pytest.mark.parametrize("source", NOT_FLAGGED)
def test_checker_passes(source: str) -> None:
    assert not column_offences(source), source


def test_checker_knows_every_key() -> None:
    from crossing_env import observation

    assert KEYS == {name: getattr(observation, name) for name in dir(observation) if name.endswith("_KEY")}
    assert set(observation.OBSERVATION_KEYS) == KEY_VALUES
    assert {"PEDESTRIANS_KEY", "PREDICTED_PATHS_KEY", "CROSSING_INTENTION_KEY"} <= KEY_CONSTANTS
