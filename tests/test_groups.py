"""The named groups of arrays checked against the kernels that read them (issue 19, item 2).

Every kernel of ``clothsim.solver`` (each numba dispatcher defined there) is
parsed from its source. A parameter named after a group (``springs``,
``knobs``, ``points``, ``control``, ``scratch``, ``lists``) is that group: the
kernel may read its fields by name or hand it on whole, nothing else. Every
field a kernel reads must exist in the group and every field of a group must
be read by some kernel, so renaming a field on one side only fails here,
as does a field nobody reads any more. No kernel reads a group's field inside
a ``prange`` body (numba drops stores through a named tuple's field there),
every group is built with its fields named (no order of buffers written
outside the group's class), and no kernel takes more than MAX_PARAMETERS
parameters; the cases known to break the last three rules today are listed
exactly below, so a new one fails and a fixed one must leave the list.
Nothing here compiles a kernel.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import textwrap
from pathlib import Path

from numba.core.dispatcher import Dispatcher

import clothsim
import clothsim.solver
from clothsim.solver.groups import Control, FrameRun, Knobs, MeshKnobs, Points, Scratch
from clothsim.solver.mesh_pulls import MeshPulls
from clothsim.solver.meshsprings import MeshSprings
from clothsim.solver.selfcollide.buffers import NeighbourList
from clothsim.solver.springs import GridSprings

GROUPS = {"springs": GridSprings, "knobs": Knobs, "points": Points, "control": Control, "scratch": Scratch,
          "lists": NeighbourList, "mesh_springs": MeshSprings, "mesh_knobs": MeshKnobs, "mesh_pulls": MeshPulls,
          "frame_run": FrameRun}
"""the parameter name each group goes by in every kernel that takes it"""

MAX_PARAMETERS = 10

# Known exceptions, each an exact list: a new case fails its test, and so does
# an entry that no longer holds (remove it once the code is fixed).

LONG_SIGNATURES = {
    "_scan": 18,  # inlined into query_points: the point's and the build's values one by one
    "_inside": 17,  # inlined into _scan: the vector test's planes and scalars one by one
    "_put_checked": 15,  # inlined into _scan: the append's arrays and scalars one by one
    "_first_crossing": 12,  # inlined into the mesh kernels: the segment's ends one coordinate at a time
    "_hit": 11,  # inlined into _first_crossing: the segment and its slack as scalars, no array per point
    "_advance_mesh": 11,  # the general path's springs in two groups, lists and slots: nested, no prange takes them
}
"""kernels that take more than MAX_PARAMETERS parameters today, and how many"""

NAME_CLASHES: set[tuple[str, str]] = set()
"""(kernel, parameter) that takes a group's name for something else (none today)"""

POSITIONAL_SITES: set[str] = set()
"""groups built somewhere with fields in order (none today)"""


def solver_kernels() -> dict[str, object]:
    """Every numba dispatcher defined in clothsim.solver, by its Python function's name
    (the serial and parallel builds of one body once)."""
    kernels, seen = {}, set()
    for info in pkgutil.walk_packages(clothsim.solver.__path__, "clothsim.solver."):
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if not isinstance(obj, Dispatcher) or not obj.py_func.__module__.startswith("clothsim.solver"):
                continue
            if obj.py_func.__code__ in seen:
                continue
            seen.add(obj.py_func.__code__)
            kernels[obj.py_func.__code__.co_name] = obj.py_func
    return kernels


KERNELS = solver_kernels()


def parsed(func) -> ast.FunctionDef:
    tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    node = tree.body[0]
    assert isinstance(node, ast.FunctionDef), func
    return node


TREES = {name: parsed(func) for name, func in KERNELS.items()}


def parameters(node: ast.FunctionDef) -> list[str]:
    a = node.args
    return [p.arg for p in a.posonlyargs + a.args + a.kwonlyargs]


def group_params(node: ast.FunctionDef) -> list[str]:
    """the kernel's parameters that are groups"""
    return [p for p in parameters(node) if p in GROUPS and (node.name, p) not in NAME_CLASHES]


def with_parents(node: ast.AST):
    """(node, parent) for every node under ``node``."""
    for parent in ast.walk(node):
        for child in ast.iter_child_nodes(parent):
            yield child, parent


def group_reads(node: ast.FunctionDef) -> dict[str, set[str]]:
    """The fields each group parameter of the kernel is read by: {parameter: {field}}."""
    reads = {p: set() for p in group_params(node)}
    for child, _ in with_parents(node):
        if isinstance(child, ast.Attribute) and isinstance(child.value, ast.Name) and child.value.id in reads:
            reads[child.value.id].add(child.attr)
    return reads


def test_the_kernels_are_found():
    """the scan sees the substep and every stage's kernels (a scan that finds nothing checks nothing)"""
    for name in ("_advance", "integrate", "provot", "collide", "collide_spheres",
                 "collide_planes", "self_collide", "sort_into_cells", "query_points", "build_list"):
        assert name in KERNELS, name
    assert len(KERNELS) > 40
    takes = {group.__name__: sorted(k for k, node in TREES.items() if p in group_params(node))
             for p, group in GROUPS.items()}
    assert all(takes.values()), takes  # every group reaches some kernel


def test_every_group_is_a_named_tuple():
    for group in GROUPS.values():
        assert issubclass(group, tuple) and group._fields, group


def unknown_fields(node: ast.FunctionDef, fields: dict[str, tuple[str, ...]]) -> dict[str, set[str]]:
    """{group parameter: the fields the kernel reads of it that the group (its ``fields``) lacks}"""
    reads = group_reads(node)
    return {p: reads[p] - set(fields[p]) for p in reads if reads[p] - set(fields[p])}


def dead_fields(trees: dict[str, ast.FunctionDef], name: str, fields: tuple[str, ...]) -> set[str]:
    """The fields of group parameter ``name`` that no kernel reads by name, nor takes
    beside the group as a parameter of the field's own name."""
    used = set()
    for node in trees.values():
        used |= group_reads(node).get(name, set())
        if name in group_params(node):
            used |= set(parameters(node)) & set(fields)
    return set(fields) - used


FIELDS = {name: group._fields for name, group in GROUPS.items()}


def test_every_field_a_kernel_reads_is_in_its_group():
    """``group.field`` in a kernel names a field of that group, and is only read"""
    wrong = {}
    for kernel, node in TREES.items():
        missing = unknown_fields(node, FIELDS)
        if missing:
            wrong[kernel] = missing
        for child, _ in with_parents(node):
            if (isinstance(child, ast.Attribute) and isinstance(child.value, ast.Name)
                    and child.value.id in group_params(node) and not isinstance(child.ctx, ast.Load)):
                wrong.setdefault(kernel, {})[f"stores {child.value.id}.{child.attr}"] = child.lineno
    assert not wrong, f"kernels reading fields their groups lack: {wrong}"


def test_every_field_of_a_group_is_read_by_a_kernel():
    """no dead fields: each field is read by name in some kernel that takes the group,
    or reaches the kernels beside it as a parameter of its own name (the list's
    ``pairs``, which a build replaces, travel that way)"""
    dead = {GROUPS[name].__name__: sorted(dead_fields(TREES, name, FIELDS[name])) for name in GROUPS}
    assert not any(dead.values()), f"fields no kernel reads: {dead}"


def test_a_group_is_read_by_name_or_handed_on_whole():
    """no positional access to a group (``knobs[2]``, ``*lists``, unpacking it as a
    tuple, iterating it): each use is ``group.field``, the group as an argument, or
    a test for None; and a parameter with a group's name is that group"""
    misused = set()
    for kernel, node in TREES.items():
        for child, parent in with_parents(node):
            if not (isinstance(child, ast.Name) and child.id in GROUPS and child.id in parameters(node)):
                continue
            by_name = isinstance(parent, ast.Attribute) and parent.value is child
            handed_on = (isinstance(parent, ast.Call) and child in parent.args) or isinstance(parent, ast.keyword)
            compared = isinstance(parent, ast.Compare)  # `lists is not None`
            if not (by_name or handed_on or compared):
                misused.add((kernel, child.id))
    assert misused == NAME_CLASHES, f"group parameters used other than by name: {misused - NAME_CLASHES}"


def test_a_kernel_takes_a_group_only_under_its_name():
    """a parameter whose fields are read with the name of a group's field must be
    that group's parameter: a group taken under another name would escape the checks"""
    fields = {f for group in GROUPS.values() for f in group._fields}
    wrong = []
    for kernel, node in TREES.items():
        others = set(parameters(node)) - set(group_params(node))
        for child, _ in with_parents(node):
            if (isinstance(child, ast.Attribute) and isinstance(child.value, ast.Name)
                    and child.value.id in others and child.attr in fields):
                wrong.append(f"{kernel} reads {child.value.id}.{child.attr}")
    assert not wrong, f"name the parameter after its group ({', '.join(sorted(GROUPS))}): {wrong}"


def is_prange(loop: ast.AST) -> bool:
    if not (isinstance(loop, ast.For) and isinstance(loop.iter, ast.Call)):
        return False
    func = loop.iter.func
    return (isinstance(func, ast.Name) and func.id == "prange") or (
        isinstance(func, ast.Attribute) and func.attr == "prange")


def test_no_group_field_is_read_inside_a_prange_body():
    """numba drops stores through a named tuple's field inside a ``prange`` body
    (numba issues 5872, 7135): a kernel unpacks its groups into locals before"""
    inside = []
    loops = 0
    for kernel, node in TREES.items():
        for loop in filter(is_prange, ast.walk(node)):
            loops += 1
            for stmt in loop.body:
                for child in ast.walk(stmt):
                    if (isinstance(child, ast.Attribute) and isinstance(child.value, ast.Name)
                            and child.value.id in group_params(node)):
                        inside.append(f"{kernel}: {child.value.id}.{child.attr} (line {child.lineno})")
    assert loops >= 4  # the substep's and self-collision's
    assert not inside, inside


def enclosing_class(tree: ast.Module, target: ast.AST) -> str | None:
    for cls in ast.walk(tree):
        if isinstance(cls, ast.ClassDef) and any(n is target for n in ast.walk(cls)):
            return cls.name
    return None


def construction_sites():
    """(file, line, group name, call) of every call of a group's class in the package's
    sources, ``cls(...)`` in a group's own class methods included"""
    names = {group.__name__ for group in GROUPS.values()}
    package = Path(clothsim.__file__).parent
    for path in sorted(package.rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if not isinstance(node, ast.Call):
                continue
            func = node.func
            called = func.id if isinstance(func, ast.Name) else (func.attr if isinstance(func, ast.Attribute) else None)
            if called == "cls":
                called = enclosing_class(tree, node)
            if called in names:
                yield path.relative_to(package), node.lineno, called, node


def test_every_group_is_built_with_its_fields_named():
    """the order of a group's fields is written only in its class: every construction
    names its fields, so a reordered class cannot hand a kernel the wrong array"""
    sites = list(construction_sites())
    assert {name for _, _, name, _ in sites} == {g.__name__ for g in GROUPS.values()}  # each is built
    in_order = {name: f"{path}:{line}" for path, line, name, call in sites if call.args}
    assert set(in_order) == POSITIONAL_SITES, f"groups built with fields in order: {in_order}"


def test_no_kernel_takes_more_than_ten_parameters():
    long = {k: len(parameters(node)) for k, node in TREES.items() if len(parameters(node)) > MAX_PARAMETERS}
    assert long == LONG_SIGNATURES, {k: v for k, v in long.items() if LONG_SIGNATURES.get(k) != v}


def test_a_field_renamed_on_one_side_fails_the_checks():
    """the checks catch a rename on one side only: renamed in a kernel, the kernel
    reads a field the group lacks and the old field goes unread; renamed in the
    group, the kernels read a field it lacks and the new one goes unread"""
    assert {"k_over_m", "keep"} <= set(Knobs._fields)
    edited = dict(TREES)
    for kernel in ("integrate", "integrate_chunks", "integrate_eights"):
        source = textwrap.dedent(inspect.getsource(KERNELS[kernel])).replace("knobs.k_over_m", "knobs.k_per_m")
        edited[kernel] = ast.parse(source).body[0]
    assert unknown_fields(edited["integrate"], FIELDS) == {"knobs": {"k_per_m"}}
    assert dead_fields(edited, "knobs", FIELDS["knobs"]) == {"k_over_m"}
    renamed = {**FIELDS, "knobs": tuple("damping_keep" if f == "keep" else f for f in Knobs._fields)}
    assert unknown_fields(TREES["verlet_gather"], renamed) == {"knobs": {"keep"}}
    assert dead_fields(TREES, "knobs", renamed["knobs"]) == {"damping_keep"}
    assert dead_fields(TREES, "knobs", FIELDS["knobs"]) == set()
