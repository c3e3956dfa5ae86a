"""The package's shape (DESIGN §3): one-way imports by floors, no private names across modules,
short functions, a data-only result, and a light ``import handeye``."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "handeye"

#: Floors from the ground up (README, "Layout"): a module imports only from lower floors, or from its own
#: package. Keys are the top-level modules and packages of handeye, each on a floor of its own.
FLOORS = {
    "errors": 1, "_version": 1,
    "geometry": 2, "_shared": 2,
    "frames": 3,
    "robot": 4,
    "sensors": 5,
    "solvers": 6,
    "options": 7,
    "result": 8,
    "estimation": 9,
    "io": 10,
    "simulate": 11,
    "pipelines": 12,
    "report": 13,
    "planning": 14,
    "workflows": 15,
    "cli": 16,
    "": 17,  # "" is handeye/__init__.py, the public face
}
#: The modules at the package's root (the rest live in folders named for what they hold).
ROOT_MODULES = {"__init__", "errors", "_version", "options", "result"}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(SRC.rglob("*.py"))}


MODULES = _modules()


def _imports(name: str, path: Path):
    """(target module, imported names, lineno, local) for every import of handeye's own modules."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_pkg = path.name == "__init__.py"
    local_nodes = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                   for n in ast.walk(f) if isinstance(n, (ast.Import, ast.ImportFrom))}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_pkg else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if not target.startswith("handeye"):
                continue
            names = [a.name for a in node.names]
            submodules = [f"{target}.{n}" for n in names if f"{target}.{n}" in MODULES]
            for t in submodules or [target]:
                out.append((t, names, node.lineno, id(node) in local_nodes))
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("handeye"):
                    out.append((a.name, [], node.lineno, id(node) in local_nodes))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "lazy_module"
              and node.args and isinstance(node.args[0], ast.Constant) and str(node.args[0].value).startswith("handeye")):
            # a module loaded on first use (_shared.lazy) is an import all the same: floors and circles hold for it
            out.append((node.args[0].value, [], node.lineno, False))
    return out


EDGES = {name: _imports(name, path) for name, path in MODULES.items()}


def _top(name: str) -> str:
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else ""


def _package(name: str) -> str:
    """The package a module belongs to (a package's __init__ belongs to itself)."""
    return name if MODULES[name].name == "__init__.py" else name.rpartition(".")[0]


def test_every_module_has_a_floor():
    assert {_top(m) for m in MODULES} <= set(FLOORS), sorted({_top(m) for m in MODULES} - set(FLOORS))
    assert all(isinstance(f, int) for f in FLOORS.values())


def test_few_modules_at_the_root_and_a_folder_for_each_domain():
    """A newcomer finds the robot, the sensors, the solvers, the estimation, the pipelines, the files
    and the workflows by their folder names; at most six modules stay at the root."""
    root = {p.stem for p in SRC.glob("*.py")}
    assert root == ROOT_MODULES and len(root) <= 6, sorted(root)
    folders = {p.name for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").is_file()}
    assert {"frames", "geometry", "robot", "sensors", "solvers", "estimation", "io", "pipelines", "report",
            "planning", "workflows", "simulate", "cli"} <= folders, sorted(folders)


def test_imports_go_down_the_floors():
    wrong = []
    for src, edges in EDGES.items():
        for dst, _, line, _ in edges:
            if _top(src) == _top(dst) and _top(src):
                continue  # inside one subpackage: checked for circles below
            if FLOORS[_top(dst)] >= FLOORS[_top(src)]:
                wrong.append(f"{src}:{line} imports {dst} (floor {FLOORS[_top(dst)]} >= {FLOORS[_top(src)]})")
    assert not wrong, "\n".join(wrong)


def test_no_import_circle_counting_function_local_imports():
    graph = {src: {dst for dst, *_ in edges if dst in MODULES and dst != src} for src, edges in EDGES.items()}
    state: dict[str, int] = {}
    cycles = []

    def visit(node, stack):
        state[node] = 1
        for nxt in graph[node]:
            if state.get(nxt) == 1:
                cycles.append(" -> ".join(stack[stack.index(nxt):] + [nxt]))
            elif nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = 2

    for m in graph:
        if m not in state:
            visit(m, [m])
    assert not cycles, "\n".join(cycles)


def test_no_function_local_import_of_the_package():
    local = [f"{src}:{line} imports {dst}" for src, edges in EDGES.items() for dst, _, line, is_local in edges if is_local]
    assert not local, "\n".join(local)


def test_no_private_name_crosses_a_package():
    """A ``_name``, or a name from a ``_module``, is imported only inside the package that owns it."""
    wrong = []
    for src, edges in EDGES.items():
        for dst, names, line, _ in edges:
            if dst not in MODULES:
                continue
            owner = _package(dst)
            if any(part.startswith("_") and not part.startswith("__") for part in dst.split(".")[1:]):
                # a private module (solvers._common) or package (_shared): only from inside its parent
                private_parent = dst.split(".")
                idx = next(i for i, p in enumerate(private_parent) if i > 0 and p.startswith("_") and not p.startswith("__"))
                scope = ".".join(private_parent[:idx])
                if not (src == scope or src.startswith(scope + ".")):
                    wrong.append(f"{src}:{line} imports from the private module {dst}")
            private_names = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if private_names and _package(src) != owner:
                wrong.append(f"{src}:{line} imports {private_names} from {dst}")
            elif private_names and not dst.rpartition(".")[2].startswith("_"):
                wrong.append(f"{src}:{line} imports {private_names} from {dst}, which is not a _module helper")
    assert not wrong, "\n".join(wrong)


def test_no_function_over_100_lines():
    """Short functions: at most 100 lines of code (the docstring, with its Examples, not counted)."""
    long = []
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                doc = node.body[0]
                if isinstance(doc, ast.Expr) and isinstance(doc.value, ast.Constant) and isinstance(doc.value.value, str):
                    n -= doc.end_lineno - doc.lineno + 1
                if n > 100:
                    long.append(f"{name}.{node.name}: {n} lines")
    assert not long, "\n".join(long)


def test_the_result_type_writes_no_files():
    import handeye.result as result

    source = Path(result.__file__).read_text(encoding="utf-8")
    assert not hasattr(result.Calibration, "write")
    for word in ("open(", "atomic_write", "write_text", "write_bytes", "savefig", "mkdir"):
        assert word not in source, word
    assert {dst for dst, *_ in EDGES["handeye.result"]} <= {
        m for m in MODULES if FLOORS[_top(m)] < FLOORS["result"]}


@pytest.mark.parametrize("statement", ["import handeye", "import handeye.cli"])
def test_import_loads_neither_opencv_matplotlib_nor_scipy_stats(statement):
    code = (f"{statement}; import sys; "
            "print(sorted(m for m in ('cv2', 'matplotlib', 'scipy.stats') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("argv", [["--help"], ["calibrate", "--help"], ["check", "--sample", "--folds", "1"],
                                  ["calibrate-poses", "--no-such-option"]])
def test_a_command_imports_no_other_command(argv):
    """``handeye --help`` imports no command's module, and a command (parsed, or refused) imports its
    own module alone: every command does not pay for the others' imports (issue 81)."""
    from handeye import cli

    modules = {f"handeye.cli.{module}" for module, _ in cli.COMMANDS.values()}
    code = (f"import sys; from handeye.cli import main; status = main({argv!r}); "
            f"print(sorted(m for m in {sorted(modules)!r} if m in sys.modules)); print(status)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.splitlines()
    command = next((a for a in argv if not a.startswith("-")), None)
    assert out[-2] == str([] if command is None else [f"handeye.cli.{cli.COMMANDS[command][0]}"]), out
    assert out[-1] == ("0" if argv[-1] == "--help" else "2"), out
    if command is None:  # every command is listed all the same
        assert all(name in "\n".join(out) for name in cli.COMMANDS)


def test_setup_branches_live_in_setups():
    """What differs between eye-in-hand and eye-to-hand is decided in setups.py alone."""
    found = []
    for name, path in MODULES.items():
        if name == "handeye.frames.setups":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Compare) and any(isinstance(c, ast.Constant) and c.value in ("eye_in_hand", "eye_to_hand")
                                                     for c in node.comparators + [node.left]):
                found.append(f"{name}:{node.lineno}")
    assert not found, found


@pytest.mark.slow
def test_every_error_a_user_can_see_is_a_handeye_error_from_errors_py():
    """Exceptions are defined in errors.py only, and handeye raises its own types (which keep
    ValueError as a base where callers caught it): no bare ValueError, TypeError, RuntimeError or
    KeyError is raised on purpose anywhere in the package."""
    bare, classes = [], []
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call) and isinstance(node.exc.func, ast.Name) \
                    and node.exc.func.id in ("ValueError", "TypeError", "RuntimeError", "KeyError"):
                bare.append(f"{name}:{node.lineno} raises {node.exc.func.id}")
            if isinstance(node, ast.ClassDef) and name != "handeye.errors" and any(
                    isinstance(b, ast.Name) and b.id.endswith(("Error", "Exception")) for b in node.bases):
                classes.append(f"{name}.{node.name}")
    assert not bare, "\n".join(bare)
    assert not classes, "exception classes outside errors.py: " + ", ".join(classes)


def test_docstrings_cite_sources_by_name_not_by_files_outside_the_repository():
    """'DESIGN §4' and the seed files' names point at files a user of the package does not have."""
    found = [f"{name}:{i}" for name, path in MODULES.items()
             for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if "DESIGN §" in line or "001_..." in line or "000_75db" in line or "shared/seeds" in line]
    assert not found, "\n".join(found)


def test_the_command_line_is_one_module_per_command():
    """cli/ holds one module per command: its ``register`` adds exactly that command's parser, and the
    calibration options are defined once, in cli/_common.py, for every command that calibrates."""
    import argparse

    from handeye import cli

    parser = cli.build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))  # noqa: SLF001
    seen = {}
    for command, (_, line) in cli.COMMANDS.items():
        module = cli.command_module(command)
        sub = argparse.ArgumentParser().add_subparsers()
        module.register(sub)
        names = list(sub.choices)
        assert names == [command], (module.__name__, names)
        assert [a.help for a in sub._choices_actions] == [line], command  # noqa: SLF001  (what --help lists)
        seen[names[0]] = module.__name__
    assert sorted(seen) == sorted(action.choices)
    files = {p.stem for p in (SRC / "cli").glob("*.py")} - {"__init__", "__main__", "_common", "_printing"}
    assert files == {m.rsplit(".", 1)[1] for m in seen.values()}
    defining = [p.name for p in (SRC / "cli").glob("*.py") if "def add_calibrate_options" in p.read_text()]
    assert defining == ["_common.py"]
    for name in ("calibrate", "calibrate-poses", "calibrate-streams", "check"):
        options = {o for a in action.choices[name]._actions for o in a.option_strings}  # noqa: SLF001
        assert {"--refine", "--method", "--robot-accuracy", "--known"} <= options, name


def test_a_target_type_is_one_module_and_one_registration():
    """sensors/camera/targets/ holds one module per target type, each defining one Target class that the
    registry knows; nothing else in the package switches on a target's class or type name (the
    renderer, the printer and `handeye target` ask the class)."""
    from handeye.sensors.camera import targets

    folder = SRC / "sensors" / "camera" / "targets"
    modules = sorted(p.stem for p in folder.glob("*.py") if p.stem not in ("__init__", "base"))
    registered = {cls.__module__.rsplit(".", 1)[1]: cls for cls in (targets.target_from_spec.__globals__["_REGISTRY"]).values()}
    assert sorted(registered) == modules
    for stem in modules:
        tree = ast.parse((folder / f"{stem}.py").read_text(encoding="utf-8"))
        classes = [n.name for n in tree.body if isinstance(n, ast.ClassDef)]
        assert classes == [registered[stem].__name__], (stem, classes)
    names = {cls.__name__ for cls in registered.values()}
    kinds = set(targets.target_types())
    switches = []
    for name, path in MODULES.items():
        if name.startswith("handeye.sensors.camera.targets"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "isinstance":
                if {n.id for n in ast.walk(node.args[1]) if isinstance(n, ast.Name)} & names:
                    switches.append(f"{name}:{node.lineno} isinstance")
            if isinstance(node, ast.Compare) and any(isinstance(c, ast.Constant) and c.value in kinds
                                                     for c in node.comparators + [node.left]):
                switches.append(f"{name}:{node.lineno} compares with a target type")
    assert not switches, "\n".join(switches)


@pytest.mark.parametrize("old", ["handeye.calibration", "handeye.vision.targets", "handeye.depth", "handeye.kinematics"])
def test_moved_modules_import_from_their_old_path_with_a_deprecation_warning(old):
    """One release of grace: the old path imports, warns where to import from, and forwards every name."""
    code = (f"import warnings; warnings.simplefilter('error')\n"
            f"try:\n    import {old}\nexcept DeprecationWarning as w:\n    print('warned', w)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    parent = old.rsplit(".", 1)[0] if old.count(".") > 1 else old  # an old package's path warns first
    assert out.startswith(f"warned {parent} has moved: import from handeye."), out
    with pytest.warns(DeprecationWarning):
        module = __import__(old, fromlist=["_"])
    from handeye import MOVED

    for target in MOVED[old]:
        new = __import__(target, fromlist=["_"])
        for name in getattr(new, "__all__", []):
            assert getattr(module, name) is getattr(new, name), (old, name)
    with pytest.raises(AttributeError, match="moved to"):
        module.no_such_name  # noqa: B018


def test_the_setup_is_checked_once_per_call_and_travels_inward(monkeypatch):
    """Issue 59: a setup name is checked where it enters (``check_setup`` makes a :class:`Setup`),
    and the functions it travels into do not check it again: one calibration of pose pairs, with
    its check, its estimators and its uncertainty, validates the string once. A Setup is a str
    everywhere (JSON, YAML, pickling) and its names come with it."""
    import json
    import pickle

    import numpy as np
    import yaml

    import handeye
    from handeye.frames import setups
    from handeye.simulate import Noise, add_noise, random_scene

    class Counting(dict):
        checks = 0

        def __contains__(self, key):
            Counting.checks += 1
            return super().__contains__(key)

    monkeypatch.setattr(setups, "_INFO", Counting(setups._INFO))
    scene = random_scene(12, "eye_to_hand", rng=0)
    target2cam = add_noise(scene.target2cam, Noise(rot_deg=0.02, trans_mm=0.2), np.random.default_rng(0))
    Counting.checks = 0  # the simulator checked its own
    cal = handeye.calibrate_poses(scene.flange2base, target2cam, "eye_to_hand", progress=False)
    assert Counting.checks == 1 and type(cal.setup) is setups.Setup and cal.setup.info.x_name == "cam2base"
    assert json.loads(json.dumps({"setup": cal.setup})) == {"setup": "eye_to_hand"}
    assert yaml.safe_load(yaml.safe_dump({"setup": cal.setup})) == {"setup": "eye_to_hand"}
    assert pickle.loads(pickle.dumps(cal.setup)) is not None and pickle.loads(pickle.dumps(cal.setup)) == "eye_to_hand"
    with pytest.raises(handeye.InputMismatchError, match="unknown setup 'eye_on_hand'"):
        setups.check_setup("eye_on_hand")


def _kind_name_uses(tree: ast.AST, names: set[str], sections: set[str]) -> list[tuple[int, str]]:
    """Where ``tree`` switches on one of ``names``: compares with it (``==``, ``!=``, ``in``, ``not in``,
    a tuple or set of them too), or looks one of ``sections`` up (``x.get(name)``, ``x[name]``, a dict of
    them indexed); a result's ``figures`` are the sensor model's own record, looked up by its own keys."""
    def named(node, among) -> str | None:
        if isinstance(node, ast.Constant) and node.value in among:
            return node.value
        if isinstance(node, (ast.Tuple, ast.Set, ast.List)):
            return next((n.value for n in node.elts if isinstance(n, ast.Constant) and n.value in among), None)
        return None

    def figures(node) -> bool:
        return isinstance(node, ast.Name) and node.id == "figures" or isinstance(node, ast.Attribute) and node.attr == "figures"

    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            hit = next((h for h in (named(n, names) for n in [node.left, *node.comparators]) if h), None)
            if hit:
                found.append((node.lineno, f"compares with {hit!r}"))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in ("get", "pop") \
                and node.args and named(node.args[0], sections) and not figures(node.func.value):
            found.append((node.lineno, f"looks up {named(node.args[0], sections)!r}"))
        elif isinstance(node, ast.Subscript) and not figures(node.value) and (
                named(node.slice, sections) or isinstance(node.value, ast.Dict) and named(ast.Tuple(node.value.keys), names)):
            found.append((node.lineno, f"looks up {named(node.slice, sections) or 'a dict keyed by its names'!r}"))
    return found


def _kind_blind_uses(tree: ast.AST, sections: set[str]) -> list[tuple[int, str]]:
    """Where ``tree`` knows a kind without asking the registry: tests a sensor figure's presence
    (``"X_per_sensor" in cal.sensor.figures``: ask the result's kind, :func:`~handeye.pipelines.kinds.joins_sensors`)
    or writes one of ``sections`` in a session.yaml (a mapping with ``setup`` and ``laser``: a kind's
    session is written in its folder)."""
    def figures(node) -> bool:
        return isinstance(node, ast.Name) and node.id == "figures" or isinstance(node, ast.Attribute) and node.attr == "figures"

    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare) and isinstance(node.left, ast.Constant) and isinstance(node.left.value, str) \
                and isinstance(node.ops[0], (ast.In, ast.NotIn)) and figures(node.comparators[0]):
            found.append((node.lineno, f"tests the figure {node.left.value!r}'s presence"))
        elif isinstance(node, ast.Dict) and any(isinstance(k, ast.Constant) and k.value == "setup" for k in node.keys):
            found += [(node.lineno, f"writes the section {k.value!r}") for k in node.keys
                      if isinstance(k, ast.Constant) and k.value in sections]
    return found


def test_a_sensor_kind_is_two_folders_and_one_registration():
    """Issue 78: a kind of sensor is sensors/<kind>/ (its mathematics), pipelines/<kind>/ (its session
    reader, pipeline, simulator and planner) and one registration (pipelines/kinds.py's ``register_kind``
    of its names and hooks). calibrate, check, the rig, simulate, plan and the report look kinds up: nothing
    outside a kind's two folders compares with its section, command-line or display name, looks its
    section up or writes it, or tells its results by a figure's presence, and only the registry and other
    kinds (a rig composes its sensors') import its folders (the report draws what a sensor's sections hold)."""
    from handeye.pipelines import kinds

    registered = kinds.sensor_kinds()
    folders = {k.package.rsplit(".", 1)[1]: k for k in registered}
    assert sorted(folders) == sorted(p.name for p in (SRC / "pipelines").iterdir() if (p / "__init__.py").is_file())
    for name, kind in folders.items():
        assert (SRC / "sensors" / name / "__init__.py").is_file(), f"{name}: no sensors/{name}/ folder"
        assert kind.package == f"handeye.pipelines.{name}"
        for hook in ("calibrate", "extras", "rig_member", "rig_extras", "simulate", "plan", "members"):
            if getattr(kind, hook) is not None:
                assert callable(kind.hook(hook)), (name, hook)
    switches, imports = [], []
    for module, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        in_a_kind = module == "handeye.pipelines.kinds" or any(module.startswith(f"handeye.pipelines.{n}.") or
                                                               module == f"handeye.pipelines.{n}" for n in folders)
        for name, kind in folders.items():
            own = (f"handeye.pipelines.{name}", f"handeye.sensors.{name}")
            if any(module == o or module.startswith(o + ".") for o in own):
                continue
            # another kind's folder may name this kind in its own records (a rig's --laser option, a block's depth)
            sections = set() if in_a_kind or module.startswith("handeye.sensors.") else {kind.section}
            names = {kind.section, kind.cli, kind.display}
            switches += [f"{module}:{line} {what} (the {kind.display}'s)" for line, what in _kind_name_uses(tree, names, sections)]
            if not in_a_kind:
                # sensors/ may compose other kinds' mathematics (a rig's, a laser's ball); the rest asks the kind's hooks
                theirs = own[:1] if module.startswith("handeye.sensors.") else own
                imports += [f"{module}:{line} imports {dst}" for dst, _, line, _ in EDGES[module]
                            if any(dst == o or dst.startswith(o + ".") for o in theirs)]
        if not in_a_kind and not module.startswith("handeye.sensors."):
            switches += [f"{module}:{line} {what}" for line, what in _kind_blind_uses(tree, {k.section for k in registered})]
    assert not switches, "\n".join(switches)
    assert not imports, "\n".join(imports)


def _protocol_members() -> set[str]:
    """The members sensors/base.py's capability protocols declare (every protocol but ``SensorModel``, whose
    members every model has)."""
    tree = ast.parse((SRC / "sensors" / "base.py").read_text(encoding="utf-8"))
    return {n.name if isinstance(n, ast.FunctionDef) else n.target.id
            for c in tree.body if isinstance(c, ast.ClassDef) and c.name != "SensorModel"
            and any(getattr(b, "id", "") == "Protocol" for b in c.bases)
            for n in c.body if isinstance(n, ast.FunctionDef) or isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name)}


def test_a_sensor_capability_is_asked_of_its_protocol_not_probed_by_name():
    """Issue 78: the contract is declared (sensors/base.py, one protocol per capability); nothing asks a
    model for one with ``hasattr(model, "target_params")`` or ``getattr(model, "nuisances", ())``, which
    a type checker cannot follow and a renamed member silently defeats: ``isinstance(model, SharesTarget)``."""
    members = _protocol_members()
    assert {"target_params", "nuisances", "sections"} <= members and "setup" not in members, sorted(members)
    probes = []
    for module, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("hasattr", "getattr") \
                    and len(node.args) >= 2 and isinstance(node.args[1], ast.Constant) and node.args[1].value in members:
                probes.append(f"{module}:{node.lineno} {node.func.id}(..., {node.args[1].value!r})")
    assert not probes, "\n".join(probes)


@pytest.mark.parametrize("old, name, new", [
    ("handeye.io.laser_session", "load_laser_session", "handeye.pipelines.laser.session"),
    ("handeye.simulate.laser", "laser_scene", "handeye.pipelines.laser.simulate"),
    ("handeye.planning.laser", "plan_laser", "handeye.pipelines.laser.plan"),
    ("handeye.io.rig_session", "load_rig_session", "handeye.pipelines.rig.session"),
    ("handeye.simulate.mesh", "mesh_scene", "handeye.pipelines.depth.simulate_mesh"),
])
def test_a_kinds_old_modules_import_from_their_old_path_with_a_deprecation_warning(old, name, new):
    """Issue 78: a kind's session reader, simulator and planner left io/, simulate/ and planning/ for its
    folder; their old paths import for one release, warn where to import from, and forward every name."""
    code = (f"import warnings; warnings.simplefilter('error')\n"
            f"try:\n    import {old}\nexcept DeprecationWarning as w:\n    print('warned', w)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.startswith(f"warned {old} has moved: import from {new}"), out
    with pytest.warns(DeprecationWarning):
        module = __import__(old, fromlist=["_"])
    assert getattr(module, name) is getattr(__import__(new, fromlist=["_"]), name)


@pytest.mark.parametrize("package, name, new", [
    ("handeye.simulate", "laser_scene", "handeye.pipelines.laser.simulate"),
    ("handeye.simulate", "sphere_scene", "handeye.pipelines.depth.simulate_board"),
    ("handeye.planning", "plan_linescan", "handeye.pipelines.linescan.plan"),
    ("handeye.pipelines.laser", "calibrate_laser_session", "handeye.pipelines.laser.pipeline"),
    ("handeye.pipelines.rig", "rig_members", "handeye.pipelines.rig.pipeline"),
    ("handeye.io.extras", "check_extras", "handeye.pipelines.folders"),
    ("handeye.solvers.refine", "refine_pose", "handeye.estimation.refinement"),
    ("handeye.solvers.refine", "refine_reprojection", "handeye.estimation.refinement"),
])
def test_names_that_left_a_package_still_import_from_it_with_a_deprecation_warning(package, name, new):
    """Issue 78: ``from handeye.simulate import laser_scene`` and ``from handeye.pipelines.laser import
    calibrate_laser_session`` (a module that became the laser's folder) keep working one release."""
    import importlib

    with pytest.warns(DeprecationWarning, match=f"{package}.{name} has moved: import it from {new}"):
        value = getattr(importlib.import_module(package), name)
    assert value is getattr(importlib.import_module(new), name)
    with pytest.raises(AttributeError, match="no attribute"):
        getattr(importlib.import_module(package), "no_such_name")
