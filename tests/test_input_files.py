"""Every file a user names is read bounded (issue 24, "unbounded reads").

Configs, recordings (``fit --data``), step response files (``fit FILE``) and command files
(``simulate --command``) are read by one function, :func:`cas_freq.core.fileio.read_input`: only a
regular file (a symbolic link to one is fine), at most a stated size. Before, ``/dev/zero``
ended in ``MemoryError``, a named pipe as a config blocked forever, a 10 MB CSV line gave a
``_csv.Error`` traceback and 10,000 unknown keys a 1.86 MB error line.
"""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from clirun import run_cli

from cas_freq.config.loader import default_config_path
from cas_freq.core.exceptions import listed
from cas_freq.core.fileio import MAX_DATA_BYTES

REPO = Path(__file__).resolve().parents[1]

HEADER = "t [s],command_fin [deg],delta [deg]\n"


def _guarded(cases, timeout=60):
    """(exit status, stderr) of ``cas-freq ARGV`` for each ARGV of ``cases``, run in a child
    process whose address space is capped at 2 GB (a read of /dev/zero fails at once instead
    of filling the machine's memory) and killed after ``timeout`` s (a read that blocks on a
    named pipe fails the test instead of hanging it)."""
    script = textwrap.dedent(f"""
        import json, resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
        sys.path.insert(0, {str(REPO / "tests")!r})
        from clirun import run_cli
        results = []
        for argv in json.loads(sys.argv[1]):
            try:
                code, _, err = run_cli(argv)
            except BaseException as exc:  # noqa: BLE001 - reported to the test
                code, err = "exception", f"{{type(exc).__name__}}: {{str(exc)[:200]}}"
            results.append((code, err))
        print(json.dumps(results))
    """)
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    try:
        done = subprocess.run([sys.executable, "-c", script, json.dumps(cases)], env=env,
                              capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        pytest.fail(f"cas-freq did not finish within {timeout} s (a blocking read?)")
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


@pytest.mark.skipif(not os.path.exists("/dev/zero") or not hasattr(os, "mkfifo"),
                    reason="needs /dev/zero and named pipes (POSIX)")
def test_devices_and_named_pipes_are_refused_without_reading(tmp_path):
    zero_csv, zero_yaml = tmp_path / "zero.csv", tmp_path / "zero.yaml"
    zero_csv.symlink_to("/dev/zero")
    zero_yaml.symlink_to("/dev/zero")
    fifo_yaml, fifo_csv = tmp_path / "fifo.yaml", tmp_path / "fifo.csv"
    os.mkfifo(fifo_yaml)
    os.mkfifo(fifo_csv)
    cases = {
        "character device": [["fit", "--data", str(zero_csv)],
                             ["fit", str(zero_csv), "--step", "10deg"],
                             ["simulate", "--command", str(zero_csv)],
                             ["analyze", str(zero_yaml)]],
        "named pipe (FIFO)": [["analyze", str(fifo_yaml)],
                              ["fit", "--data", str(fifo_csv)],
                              ["simulate", "--command", str(fifo_csv)]],
    }
    argvs = [argv for group in cases.values() for argv in group]
    results = iter(_guarded(argvs))
    for kind, group in cases.items():
        for argv in group:
            code, err = next(results)
            path = argv[2] if argv[1] == "--data" or argv[1] == "--command" else argv[1]
            assert code == 2, (argv, err)
            assert err.startswith(f"cas-freq {argv[0]}: error: {path}: cannot read "), err
            assert f"{kind}, not a regular file" in err and err.count("\n") == 1, err


def test_a_folder_is_refused(tmp_path):
    for argv, what in ((["fit", "--data", str(tmp_path)], "recording"),
                       (["analyze", str(tmp_path)], "config file")):
        code, _, err = run_cli(argv)
        assert code == 2 and f"{tmp_path}: cannot read {what} (a folder, not a regular " \
            "file)" in err, err


def test_a_data_file_over_the_size_limit(tmp_path):
    """A recording one byte over the limit is refused from its size (a sparse file: nothing
    is written or read); one at the limit is read (and then fails on its content)."""
    path = tmp_path / "big.csv"
    with open(path, "wb") as stream:
        stream.write(HEADER.encode())
        stream.truncate(MAX_DATA_BYTES + 1)
    code, _, err = run_cli(["fit", "--data", str(path)])
    assert code == 2 and f"larger than {MAX_DATA_BYTES} bytes, the limit for recordings" \
        in err, err
    os.truncate(path, MAX_DATA_BYTES)
    code, _, err = run_cli(["fit", "--data", str(path)])
    assert code == 2 and "larger than" not in err, err


@pytest.mark.parametrize("command", [["fit", "--data", "{}"], ["fit", "{}", "--step", "10deg"],
                                     ["simulate", "--command", "{}"]])
def test_a_10_mb_line_is_one_line_of_error(tmp_path, command):
    path = tmp_path / "long.csv"
    path.write_text(HEADER + "0," + "1" * (10 << 20) + ",0\n")
    code, _, err = run_cli([part.format(path) for part in command])
    assert code == 2, err
    # the csv module's own limit on a field (131,072 characters), named with the line
    assert f"{path}: line 2: a cell longer than 131,072 characters" in err
    assert err.count("\n") == 1 and len(err) < 300


@pytest.mark.parametrize("where", ["top level", "variant"])
def test_ten_thousand_unknown_keys(tmp_path, where):
    text = default_config_path().read_text(encoding="utf-8")
    if where == "top level":
        text += "".join(f"\njunk_{i}: {i}" for i in range(10_000))
        first = "junk_0"
    else:
        keys = "".join(f"\n    motor.junk_{i}: {i}" for i in range(10_000))
        assert "\nvariants:" in text
        text = text.replace("\nvariants:", f"\nvariants:\n  many:{keys}", 1)
        first = "motor.junk_0"
    path = tmp_path / "keys.yaml"
    path.write_text(text, encoding="utf-8")
    code, _, err = run_cli(["analyze", str(path)])
    assert code == 2
    assert len(err) < 2000, len(err)
    assert f"10,000 unknown keys: {first}, " in err and "... and 9,990 more" in err
    assert "accepts" in err  # what the section takes, said once


def test_many_unknown_requirement_metrics_list_the_accepted_figures_once(tmp_path):
    # 2,000 requirements on unknown figures: the error is cut after 10 problems, but each of
    # the 10 repeated the ~100 accepted figure keys (16 KB on one line); now said once.
    text = default_config_path().read_text(encoding="utf-8")
    bad = "".join(f"\n  - {{id: X{i}, metric: no.figure{i}, min: 1, severity: required, "
                  "source: test}" for i in range(2000))
    text = text.replace("\nrequirements:", "\nrequirements:" + bad, 1)
    path = tmp_path / "requirements.yaml"
    path.write_text(text, encoding="utf-8")
    code, _, err = run_cli(["analyze", str(path)])
    assert code == 2 and err.count("\n") == 1 and "... and 1,990 more" in err
    assert err.count("closed_loop.bandwidth_rad_s") == 1 and err.count("accepted: as above") == 9
    assert len(err) < 4000, len(err)


def test_a_header_of_ten_thousand_cells_is_cut(tmp_path):
    path = tmp_path / "wide.csv"
    path.write_text(",".join(f"x{i}" for i in range(10_000)) + "\n")
    code, _, err = run_cli(["fit", "--data", str(path)])
    assert code == 2 and "... and 9,990 more" in err and len(err) < 2000, err[:500]


def test_listed():
    assert listed(["a", "b"]) == "a; b"
    assert listed([str(i) for i in range(12)], ", ", most=10) == \
        "0, 1, 2, 3, 4, 5, 6, 7, 8, 9, ... and 2 more"
