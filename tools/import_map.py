"""`python -m tools.import_map`: the direct imports between the project's packages, counted from grimp's graph (the
library import-linter builds its contracts on), and those that run from a lower layer to a higher one or from one door
to the other (ARCHITECTURE.md, "Layers"; the pyproject's `layers` contract enforces the same rule, this prints it).

Lowest first: rubric, grader.core, grader.services, grader.web, the doors grader.api and grader.pages, grader.main.
Entry points (cli, embedded, dispatch, reconcile, ops, client) and the worker stand beside the layers and are
counted, never ranked."""

from __future__ import annotations

from collections import Counter

RANK = {"rubric": 0, "grader.core": 1, "grader.services": 2, "grader.web": 3, "grader.api": 4, "grader.pages": 4,
        "grader.main": 5}
DOORS = {"grader.api", "grader.pages"}


def package(module: str) -> str:
    """The package a module counts under: a ranked layer, `worker`, or grader's top-level module."""
    for name in sorted(RANK, key=len, reverse=True):
        if module == name or module.startswith(name + "."):
            return name
    return "worker" if module.split(".")[0] == "worker" else ".".join(module.split(".")[:2])


def import_map(graph=None) -> tuple[Counter, list[tuple[str, str]]]:
    """(imports per (from, to) package pair, every import that runs upward or door to door) of `graph` (a grimp
    graph; by default the project's own)."""
    if graph is None:
        import grimp

        graph = grimp.build_graph("grader", "worker", "rubric")
    between: Counter = Counter()
    wrong: list[tuple[str, str]] = []
    for module in graph.modules:
        for imported in graph.find_modules_directly_imported_by(module):
            a, b = package(module), package(imported)
            if a == b:
                continue
            between[(a, b)] += 1
            if (a in RANK and b in RANK and RANK[b] > RANK[a]) or (a in DOORS and b in DOORS):
                wrong.append((module, imported))
    return between, sorted(wrong)


def main() -> int:
    between, wrong = import_map()
    print(f"imports between packages: {sum(between.values())}")
    for (a, b), n in sorted(between.items()):
        print(f"  {a:20} -> {b:20} {n}")
    print(f"running upward or door to door: {len(wrong)}")
    for module, imported in wrong:
        print(f"  {module} -> {imported}")
    return 1 if wrong else 0


if __name__ == "__main__":
    raise SystemExit(main())
