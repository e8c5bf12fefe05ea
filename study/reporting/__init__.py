"""Tables, figures, the HTML report and the paper, made from the engine's results
(study.engine.results) alone: nothing here reads the cache's store or runs a task."""
