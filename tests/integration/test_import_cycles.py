"""No import cycle between any two modules of the project (docs/ARCHITECTURE.md, "Layers and contracts").

The graph is grimp's (the one lint-imports checks): every import counts, also one inside a function or under
``if TYPE_CHECKING:``. A package counts as the module of its ``__init__``.
"""

from __future__ import annotations

import grimp
import networkx as nx

PACKAGES = ("uvdms_gym", "baselines", "agents", "leaderboard", "uvdms_cli")


def import_cycles(graph: nx.DiGraph) -> list[list[str]]:
    """The strongly connected components of more than one module, and the modules that import themselves."""
    components = [sorted(c) for c in nx.strongly_connected_components(graph) if len(c) > 1]
    return sorted(components + [[node] for node, _ in nx.selfloop_edges(graph)])


def test_the_finder_finds_a_planted_cycle():
    graph = nx.DiGraph([("a", "b"), ("b", "c"), ("c", "a"), ("d", "a"), ("e", "e"), ("f", "d")])
    assert import_cycles(graph) == [["a", "b", "c"], ["e"]]


def test_no_import_cycle_between_modules():
    imports = grimp.build_graph(*PACKAGES, include_external_packages=False)
    graph = nx.DiGraph()
    graph.add_nodes_from(imports.modules)
    graph.add_edges_from((m, i) for m in imports.modules for i in imports.find_modules_directly_imported_by(m))
    assert graph.number_of_edges() > 300  # the whole project was read
    cycles = import_cycles(graph)
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)
