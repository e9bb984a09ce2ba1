# Cohort's import check of a `kind = "python"` class, run by `orchestrator check` and `launch` in a
# child interpreter (so that a module whose import crashes or hangs is a named error, not a dead
# orchestrator). argv: FILE CLASS ROLE; prints one JSON line: {"ok": true} or {"error": "..."}.
import importlib.util
import inspect
import json
import sys
import traceback

METHODS = {
    "algorithm": {
        "__init__": ["ctx"],
        "columns": [],
        "share": ["k", "t_s", "y"],
        "step": ["dt_s", "neighbours"],
        "row": [],
        "save_state": [],
        "restore_state": ["state"],
    },
    "plant": {
        "__init__": ["ctx"],
        "columns": [],
        "readings": ["agent", "rng"],
        "apply_command": ["agent", "u"],
        "advance": ["dt_s"],
        "row": [],
    },
}
OPTIONAL = {"algorithm": {"roster": ["live"]}, "plant": {"metrics": []}}
# A second signature a method may have instead: step also gets each share's age, in steps.
ALTERNATIVE = {"step": ["dt_s", "neighbours", "ages"]}


def takes(fn, wanted):
    """Whether fn (a method of the class, self first) accepts len(wanted) positional arguments."""
    try:
        params = list(inspect.signature(fn).parameters.values())[1:]
    except (TypeError, ValueError):
        return True  # a builtin or C method: cannot tell, let the run say
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    if any(p.kind == p.VAR_POSITIONAL for p in params):
        return len([p for p in positional if p.default is p.empty]) <= len(wanted)
    required = [p for p in positional if p.default is p.empty]
    return len(required) <= len(wanted) <= len(positional)


def check(path, name, role):
    try:
        import numpy  # noqa: F401
    except Exception as e:
        return f"cannot import numpy ({type(e).__name__}: {e}) in {sys.prefix}: install it with `python3 -m pip install numpy`"
    spec = importlib.util.spec_from_file_location("cohort_check", path)
    if spec is None:
        return f"{path}: not a Python module Python can load"
    module = importlib.util.module_from_spec(spec)
    sys.modules["cohort_check"] = module
    try:
        spec.loader.exec_module(module)
    except BaseException as e:
        last = traceback.format_exception_only(type(e), e)[-1].strip()
        return f"importing {path} raised {last}"
    cls = getattr(module, name, None)
    if cls is None:
        return f'{path} defines no class "{name}"'
    if not inspect.isclass(cls):
        return f'{path}: "{name}" is not a class'
    for method, wanted in METHODS[role].items():
        fn = getattr(cls, method, None)
        if method != "__init__" and fn is None:
            return f"class {name} has no method {method}({', '.join(wanted)}) (a {role} needs it)"
        other = ALTERNATIVE.get(method)
        if fn is not None and not takes(fn, wanted) and not (other and takes(fn, other)):
            either = f"({', '.join(['self'] + wanted)})" + (f" or ({', '.join(['self'] + other)})" if other else "")
            return f"{name}.{method} must take {either}, not {inspect.signature(fn)}"
    for method, wanted in OPTIONAL[role].items():
        fn = getattr(cls, method, None)
        if fn is not None and not takes(fn, wanted):
            return f"{name}.{method} must take ({', '.join(['self'] + wanted)}), not {inspect.signature(fn)}"
    return None


if __name__ == "__main__":
    error = check(sys.argv[1], sys.argv[2], sys.argv[3])
    print(json.dumps({"ok": True} if error is None else {"error": error}))
