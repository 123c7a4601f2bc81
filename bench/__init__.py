"""stormlane's benchmarks: ``make bench`` (= ``python -m bench``) runs them all.

Each ``bench/<name>.py`` builds its groups of sides and measures (:mod:`bench._harness`); the
driver (:mod:`bench.__main__`) runs them, writes ``bench/results.json`` and generates the
README's table and ``docs/benchmarks.md`` from it (:mod:`bench._report`).
"""
