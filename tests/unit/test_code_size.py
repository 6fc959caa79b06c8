"""Code size (issue 25): no source file over 500 lines and no function over 80 lines in
ros_ws/src/*/ (Python and C++), tools/ and scripts/, outside generated code (build/ folders).

- Python: a function's length is ``end_lineno - lineno + 1`` of its ``def`` node (ast), methods and
  nested functions each on their own (a nested function counts in its outer one's length too).
- C++: comments and string literals are blanked, then braces are matched; a brace block whose
  header (the text since the last ``;``, ``{`` or ``}``) has a parameter list ``(...)`` and does
  not open a namespace, class, struct, union, enum or ``extern "C"`` scope is a function body
  (``PYBIND11_MODULE(...) {`` included); its length runs from the header's first line to the
  closing brace. Scopes are searched for functions; other blocks (initialisers) are skipped. Good
  enough for these sources' plain style, not a C++ parser.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

REPO = next(p for p in Path(__file__).resolve().parents if (p / "ros_ws" / "src").is_dir())
MAX_FILE_LINES = 500
MAX_FUNCTION_LINES = 80
PY, CPP = {".py"}, {".cpp", ".cc", ".hpp", ".h"}
#: folders of generated or installed code, not searched
SKIP = {"build", "__pycache__", ".venv", "install", "log"}


def _sources() -> list[Path]:
    roots = [p for p in sorted((REPO / "ros_ws" / "src").iterdir()) if p.is_dir()]
    roots += [REPO / "tools", REPO / "scripts"]
    files = []
    for root in roots:
        for f in sorted(root.rglob("*")):
            rel = f.relative_to(root).parts
            if f.is_file() and not SKIP & set(rel[:-1]) and (f.suffix in PY | CPP or _python_script(f)):
                files.append(f)
    return files


def _python_script(f: Path) -> bool:
    """An extension-less executable Python script (scripts/flip)."""
    if f.suffix:
        return False
    try:
        return f.read_text().startswith("#!") and "python" in f.read_text().splitlines()[0]
    except (UnicodeDecodeError, OSError):
        return False


def _python_functions(f: Path) -> list[tuple[str, int, int]]:
    """(qualified name, first line, length) of each function in a Python file."""
    out = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = prefix + child.name
                out.append((name, child.lineno, child.end_lineno - child.lineno + 1))
                visit(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")
            else:
                visit(child, prefix)

    visit(ast.parse(f.read_text(), filename=str(f)), "")
    return out


def _blank_cpp(text: str) -> str:
    """The C++ text with comments, string and character literals replaced by spaces (newlines
    kept, so line numbers hold)."""
    pattern = re.compile(r'//[^\n]*|/\*.*?\*/|R"(\w*)\(.*?\)\1"|"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\'', re.S)
    return pattern.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)


_SCOPE = re.compile(r"^\s*(template\s*<.*>\s*)?(namespace|class|struct|union|enum|extern)\b", re.S)


def _cpp_functions(f: Path) -> list[tuple[str, int, int]]:
    """(name, first line, length) of each function body found by brace matching in a C++ file."""
    text = _blank_cpp(f.read_text())
    out = []

    def match(i):
        """Index of the brace closing the one at i."""
        depth = 0
        for j in range(i, len(text)):
            if text[j] == "{":
                depth += 1
            elif text[j] == "}":
                depth -= 1
                if depth == 0:
                    return j
        raise ValueError(f"{f}: unbalanced braces")

    def scan(start, end):
        head = start
        i = start
        while i < end:
            c = text[i]
            if c in ";}":
                head = i + 1
            elif c == "{":
                header = text[head:i]
                close = match(i)
                if _SCOPE.match(header) and not re.search(r"\)\s*$", header):
                    scan(i + 1, close)
                elif re.search(r"\)[\w\s:,()&<>\[\]-]*$", header) and "=" not in header.split("(")[0]:
                    first = head + len(header) - len(header.lstrip())
                    line0 = text.count("\n", 0, first) + 1
                    name = re.findall(r"([~\w:]+)\s*\(", header)
                    out.append((name[0] if name else "?", line0, text.count("\n", first, close) + 1))
                i = close
                head = close + 1
            i += 1

    scan(0, len(text))
    return out


def _offenders() -> tuple[list[str], list[str]]:
    files, functions = [], []
    for f in _sources():
        rel = f.relative_to(REPO)
        n = len(f.read_text().splitlines())
        if n > MAX_FILE_LINES:
            files.append(f"{rel}: {n} lines")
        found = _cpp_functions(f) if f.suffix in CPP else _python_functions(f)
        functions += [f"{rel}:{line} {name}: {length} lines" for name, line, length in found if length > MAX_FUNCTION_LINES]
    return files, functions


def test_the_checker_sees_the_sources():
    names = {f.name for f in _sources()}
    assert {"sim_node.py", "rcl_io.cpp", "tick.cpp", "launcher.py", "bench_landings.py"} <= names


def test_cpp_functions_are_found():
    """The brace matcher finds the C++ functions (a sanity check of the counting itself)."""
    tick = next(f for f in _sources() if f.name == "tick.cpp")
    found = _cpp_functions(tick)
    assert len(found) >= 3 and all(length >= 1 for _, _, length in found)


def test_no_source_file_over_500_lines():
    files, _ = _offenders()
    assert not files, "files over %d lines:\n  %s" % (MAX_FILE_LINES, "\n  ".join(files))


def test_no_function_over_80_lines():
    _, functions = _offenders()
    assert not functions, "functions over %d lines:\n  %s" % (MAX_FUNCTION_LINES, "\n  ".join(functions))


if __name__ == "__main__":
    for line in sum(_offenders(), []):
        print(line)
