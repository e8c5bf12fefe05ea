"""The TAA study, in layers; each imports only those above it in this list (tests/test_layers.py):

  metrics     image metrics on arrays alone: SSIM, volume SSIM, FLIP, the thesis's metrics
  config      what a study compares: techniques, protocols, profiles, study files, defaults
  engine      plan -> tasks -> execute -> store: references, runs, metrics, agreement, costs
  reporting   tables, figures, the HTML report and the paper, from the engine's results alone
  commands    the `taa-study` command line: run, ab, bench, estimate, paper, ...
"""


def _defer_colour_plotting() -> None:
    """colour-science's package imports its plotting stack (matplotlib, networkx, its datasets):
    1.5 s of every process that encodes a display image (an `ab`, each Dask worker, each test
    process), none of which plots with it. `colour.plotting` starts as a stand-in that imports the
    real subpackage on its first attribute access; nothing else of colour changes. Here, not in
    display/, so that no artefact is re-keyed (tests/test_keys.py)."""
    import importlib
    import importlib.util
    import sys
    import types
    if "colour" in sys.modules or "colour.plotting" in sys.modules:
        return
    spec = importlib.util.find_spec("colour")      # a top-level package: found, not imported
    if spec is None or not spec.submodule_search_locations:
        return
    from importlib.machinery import PathFinder
    sub = PathFinder.find_spec("colour.plotting", list(spec.submodule_search_locations))
    if sub is None:
        return
    stand_in = types.ModuleType("colour.plotting", "colour.plotting, imported on first use")
    stand_in.__spec__, stand_in.__path__ = sub, list(sub.submodule_search_locations or [])

    def __getattr__(name: str):
        if sys.modules.get("colour.plotting") is stand_in:
            del sys.modules["colour.plotting"]
        real = importlib.import_module("colour.plotting")
        if "colour" in sys.modules:
            sys.modules["colour"].plotting = real
        return getattr(real, name)

    stand_in.__getattr__ = __getattr__
    sys.modules["colour.plotting"] = stand_in


_defer_colour_plotting()
