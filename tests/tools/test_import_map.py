"""tools.import_map counts the imports between packages and names every one that runs upward: none on the tree,
each kind found in a graph that has them."""

from __future__ import annotations

import grimp

from tools.import_map import import_map, package


def test_the_project_has_no_import_running_upward_or_door_to_door():
    between, wrong = import_map()
    assert wrong == []
    assert between[("grader.services", "grader.core")] > 0 and between[("grader.pages", "grader.services")] > 0
    assert ("grader.core", "grader.services") not in between


def test_an_upward_and_a_door_to_door_import_are_named():
    graph = grimp.ImportGraph()
    for module in ("grader.core.models", "grader.services.setup.courses", "grader.api.routes.health",
                   "grader.pages.setup.courses", "grader.cli.course", "worker.tasks"):
        graph.add_module(module)
    graph.add_import(importer="grader.services.setup.courses", imported="grader.core.models")  # down: fine
    graph.add_import(importer="grader.core.models", imported="grader.services.setup.courses")  # up
    graph.add_import(importer="grader.pages.setup.courses", imported="grader.api.routes.health")  # door to door
    graph.add_import(importer="grader.cli.course", imported="grader.pages.setup.courses")  # entry point: not ranked
    between, wrong = import_map(graph)
    assert wrong == [("grader.core.models", "grader.services.setup.courses"),
                     ("grader.pages.setup.courses", "grader.api.routes.health")]
    assert sum(between.values()) == 4
    assert package("worker.tasks") == "worker" and package("grader.cli.course") == "grader.cli"
