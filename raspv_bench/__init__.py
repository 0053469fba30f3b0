"""RASPV-py benchmarks (`raspv bench NAME`): figures and ratios against peers run side by side.

The top floor: it measures every other package and uses the test harness
(:mod:`raspv_bringup.testing`) to start graphs; nothing below imports it (the ``raspv`` command
dispatches ``bench`` by name, :mod:`raspv_bench.bench_cli`). Each bench has a quick mode the test
suite runs (tests/bench). A development tool: not part of the colcon workspace.
"""
