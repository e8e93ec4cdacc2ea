"""How fast bad or odd input is refused or read, against its time goal (``python
benchmarks/input_speed.py``; not part of the test suite).

The cases are those of tests/test_fuzz_inputs.py (imported from it: one list of cases), which
checks what is refused and how; the time goals it asserted until issue 24 are measured here,
so the tests check behaviour, not the speed of the machine they run on:

1. ``cas-freq analyze --set KEY=VALUE --json`` of each of the issue's --set cases: refused
   within 5 s;
2. pathological unit expressions (``9**9**9 ohm``, ...) refused by ``to_si`` within 0.01 s
   (never evaluated);
3. the issue's YAML files (deep nesting, an alias bomb, 1 MiB, ...) refused by ``cas-freq
   analyze`` within the load budget + 1 s;
4. the issue's bad CLI arguments refused before any work, within 5 s;
5. a mutated config (hypothesis) loaded or refused within the load budget;
6. a random string read or refused by ``to_si`` within 0.1 s;
7. ``cas-freq fit FILE --step 10deg --json`` of a fuzzed CSV within 5 load budgets.

Printed: per goal, the cases, the median and the slowest time, and whether the slowest meets
the goal; exit status 1 when one does not. ``--examples N``: hypothesis examples per property
(default 60, the test suite's "ci" profile).
"""

import argparse
import contextlib
import io
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from test_fuzz_inputs import (  # noqa: E402
    CLI_CASES,
    SET_CASES,
    YAML_CASES,
    _analyze_text,
    _csv_text,
    _mutated,
    csv_rows,
    mutations,
    separators,
    strings,
)

from cas_freq.cli import main as cas_freq  # noqa: E402
from cas_freq.config import load_all_variants  # noqa: E402
from cas_freq.core.exceptions import CasFreqError  # noqa: E402
from cas_freq.core.units import to_si  # noqa: E402

#: Longest a config may take to be refused or loaded [s] (the tool's budget for reading data).
LOAD_BUDGET_S = 2.0

#: Pathological unit expressions: refused as written, never evaluated.
UNIT_BOMBS = ("9**9**9 ohm", "1 ohm**99999999", "1 (ohm^4)^4^4", "1 " + "(" * 50 + "ohm")


def timed(function, *args):
    """Seconds ``function(*args)`` took, its output to stdout and stderr discarded."""
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        started = time.perf_counter()
        try:
            function(*args)
        except (SystemExit, ValueError):  # argparse's refusal; to_si's (CasFreqError included)
            pass
        return time.perf_counter() - started


def _write_and_time(function, name, text, *args):
    """Seconds ``function(path, *args)`` took on ``text`` written to a temporary file."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / name
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        return timed(function, str(path), *args)


def _load(path):
    try:
        load_all_variants(path)
    except CasFreqError:
        pass


def _fit(path):
    cas_freq(["fit", path, "--step", "10deg", "--json"])


def property_times(strategy, measure, examples):
    """Times of ``measure(example)`` over ``examples`` hypothesis examples of ``strategy``."""
    times = []

    @settings(max_examples=examples, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(strategy)
    def run(example):
        times.append(measure(example))

    run()
    return times


def goals(examples):
    """(goal text, limit [s], times [s]) of each goal."""
    yield ("analyze --set, the issue's cases refused", 5.0,
           [timed(cas_freq, ["analyze", "--set", option, "--json"]) for option, _ in SET_CASES])
    yield ("to_si, unit expressions never evaluated", 0.01,
           [timed(to_si, text, "ohm") for text in UNIT_BOMBS])
    yield ("analyze, the issue's YAML files refused", LOAD_BUDGET_S + 1.0,
           [timed(_analyze_text, text) for text, _ in YAML_CASES.values()])
    yield ("the issue's CLI arguments refused before work", 5.0,
           [timed(cas_freq, argv) for argv, _ in CLI_CASES])
    yield ("a mutated config loaded or refused", LOAD_BUDGET_S, property_times(
        mutations, lambda changes: _write_and_time(_load, "config.yaml", _yaml(changes)),
        examples))
    yield ("to_si of a random string", 0.1, property_times(
        st.one_of(strings, st.text(max_size=200)), lambda text: timed(to_si, text, "s"),
        examples))
    yield ("fit of a fuzzed CSV", 5 * LOAD_BUDGET_S, property_times(
        st.tuples(csv_rows, separators, st.booleans()),
        lambda case: _write_and_time(_fit, "recording.csv", _csv_text(*case)), examples))


def _yaml(changes):
    import yaml

    return yaml.safe_dump(_mutated(changes), allow_unicode=True, sort_keys=False)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=60,
                        help="hypothesis examples per property (default 60)")
    args = parser.parse_args(argv)
    missed = 0
    print(f"| {'goal':<46} | cases | {'median':>11} | {'slowest':>11} | {'goal':>7} |      |")
    print(f"|{'-' * 48}|-------|{'-' * 13}|{'-' * 13}|{'-' * 9}|------|")
    for text, limit, times in goals(args.examples):
        ok = max(times) < limit
        missed += not ok
        print(f"| {text:<46} | {len(times):>5} | {statistics.median(times) * 1e3:>8.3g} ms "
              f"| {max(times) * 1e3:>8.3g} ms | {limit:>5g} s | {'ok' if ok else 'MISS':<4} |")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
