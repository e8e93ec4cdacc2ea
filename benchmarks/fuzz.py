"""Fuzz the input paths of cas-freq (issue 16): mutated and extreme configs through the CLI.

Not part of the test suite (its fast sibling is tests/test_fuzz_inputs.py, with hypothesis).
Each case is a config file written from the shipped configs/qt_cas.yaml, then
``cas-freq analyze CONFIG --json`` (and, for some, ``verify`` and ``simulate --step 10deg``) is
run in-process in a worker process with a 60 s alarm. Printed per command:

- tried, clean exit 2 (exactly one line on stderr, no traceback), exit 0 (the JSON holds only
  finite numbers or null; else counted as "non-finite JSON"), exit 1 (verify: a requirement
  failed), tracebacks (any exception out of ``main``, or an exit 2 with more than one line),
  hangs (> 60 s);
- typo strings read as a different number: a typo of a value string of the shipped config
  (decimal comma, a second dot, a blank or comma inside the number, a percent) that
  ``cas_freq.core.parameters.parse_value`` accepts with another value than the original's.

Mutated configs change 1-3 values of the shipped config (random strings, numbers of extreme
magnitude, wrong types, deleted keys, unicode, commas, typos, YAML tags, duplicate keys, deep
nesting); extreme configs are valid-looking configs with every parameter scaled by a random
factor 10**U(-k, k) (k up to 6), delays and gains set to 0 at random.

    python benchmarks/fuzz.py                       # 5000 mutated + 2000 extreme, analyze
    python benchmarks/fuzz.py --mutated 300 --extreme 100 --commands verify,simulate
    python benchmarks/fuzz.py --quick               # 200 + 100, a smoke run
"""

import argparse
import contextlib
import copy
import io
import json
import math
import multiprocessing
import os
import random
import signal
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "configs" / "qt_cas.yaml"
HANG_S = 60

#: Characters random strings are made of: digits, unit letters, operators, separators, unicode
#: and control characters.
ALPHABET = ("0123456789" * 3 + "eE.,+-*/^()%_ " + "msAVHzkgNradohmµΩ°é€中"
            + "\n\t\x00\x07\\'\"#:{}[]&!|>")


def leaf_paths(data, prefix=()):
    """Paths (tuples of keys/indices) of every scalar of a nested dict/list."""
    if isinstance(data, dict):
        for key, value in data.items():
            yield from leaf_paths(value, (*prefix, key))
    elif isinstance(data, list):
        for index, value in enumerate(data):
            yield from leaf_paths(value, (*prefix, index))
    else:
        yield prefix


def get(data, path):
    for part in path:
        data = data[part]
    return data


def put(data, path, value):
    for part in path[:-1]:
        data = data[part]
    data[path[-1]] = value


def delete(data, path):
    for part in path[:-1]:
        data = data[part]
    del data[path[-1]]


def typo(rng, text):
    """A typo of a value string that must never be read as a number: (kind, text) or None."""
    digits = [i for i, c in enumerate(text) if c.isdigit()]
    dots = [i for i, c in enumerate(text) if c == "."]
    kinds = []
    if dots:
        kinds += ["comma-for-dot", "second-dot"]
    if len(digits) >= 2:
        kinds += ["blank-in-number", "comma-in-number"]
    kinds.append("percent")
    kind = rng.choice(kinds)
    if kind == "comma-for-dot":
        i = rng.choice(dots)
        return kind, text[:i] + "," + text[i + 1:]
    if kind == "second-dot":
        i = rng.choice(dots)
        after = [j for j in digits if j > i]
        if not after:
            return None
        j = rng.choice(after)
        return kind, text[:j] + "." + text[j:]
    if kind in ("blank-in-number", "comma-in-number"):
        # between two digits of the leading number
        number_end = 0
        while number_end < len(text) and (text[number_end].isdigit() or text[number_end] in
                                          ".eE+-"):
            number_end += 1
        inner = [i for i in range(1, number_end) if text[i - 1].isdigit() and text[i].isdigit()]
        if not inner:
            return None
        i = rng.choice(inner)
        return kind, text[:i] + (" " if kind == "blank-in-number" else ",") + text[i:]
    unit = text.split(" ", 1)[1] if " " in text else ""
    if not unit or unit == "%":
        return None
    return kind, text.split(" ", 1)[0] + " %"


def extreme_number(rng):
    return rng.choice([
        float(f"1e{rng.randint(-400, 400)}") * rng.uniform(1, 10) * rng.choice([1, -1]),
        rng.choice([0, -0.0, 5e-324, 1e-300, 1e300, 1.7976931348623157e308]),
        float("nan"), float("inf"), -float("inf"),
        10 ** rng.randint(20, 200),
        -(10 ** rng.randint(1, 200)),
        rng.randint(-10, 10),
    ])


def random_string(rng):
    length = rng.choice([1, 2, 5, 10, 20, 63, 64, 65, 200, 5000])
    return "".join(rng.choice(ALPHABET) for _ in range(length))


def wrong_type(rng):
    return rng.choice([None, True, False, [], [1, 2], {}, {"a": 1}, "", "  ", 1j.imag, "yes"])


def mutate(rng, data, typos):
    """Mutate 1-3 values of ``data`` in place; typos of value strings are appended to
    ``typos`` as (dotted key, original, typo)."""
    for _ in range(rng.randint(1, 3)):
        paths = list(leaf_paths(data))
        if not paths:
            return
        path = rng.choice(paths)
        old = get(data, path)
        how = rng.random()
        if how < 0.2 and isinstance(old, str):
            made = typo(rng, old)
            if made:
                typos.append((".".join(map(str, path)), old, made[1]))
                put(data, path, made[1])
                continue
        if how < 0.35:
            put(data, path, random_string(rng))
        elif how < 0.6:
            put(data, path, extreme_number(rng))
        elif how < 0.75:
            put(data, path, wrong_type(rng))
        elif how < 0.85 and len(path) > 1:
            delete(data, path)
        elif how < 0.93 and isinstance(old, str):
            # unicode or a comma somewhere
            i = rng.randint(0, len(old))
            put(data, path, old[:i] + rng.choice([",", "，", "\u00a0", "\u200b", "Ω", "é", "\n"])
                + old[i:])
        else:
            put(data, path, str(extreme_number(rng)) + rng.choice(["", " ohm", " ms", " %",
                                                                   " A/rad", " s**9"]))


def text_mutation(rng, text):
    """A mutation of the YAML text itself (tags, duplicates, nesting, aliases)."""
    lines = text.splitlines()
    kind = rng.randrange(6)
    if kind == 0:  # a tag
        tag = rng.choice(["!!float abc", "!!int 0.5", "!!bool maybe", "!!timestamp x",
                          "!!binary '@'", "!!python/object:os.system x", "!!set {a}"])
        return text.replace("R: 0.361 ohm", f"R: {tag}")
    if kind == 1:  # duplicate a line
        i = rng.randrange(len(lines))
        return "\n".join(lines[: i + 1] + lines[i:]) + "\n"
    if kind == 2:  # deep nesting
        depth = rng.choice([40, 500, 5000])
        return text + f"extra: {'[' * depth}{']' * depth}\n"
    if kind == 3:  # alias bomb
        bomb = "a0: &a0 [x,x,x,x,x,x,x,x,x]\n" + "".join(
            f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]\n" for i in range(1, 9))
        return bomb + text
    if kind == 4:  # truncate
        return text[: rng.randrange(len(text))]
    # random bytes in a line
    i = rng.randrange(len(lines))
    j = rng.randint(0, len(lines[i]))
    lines[i] = lines[i][:j] + random_string(rng) + lines[i][j:]
    return "\n".join(lines) + "\n"


NUMERIC_KEYS = None


def extreme_config(rng, base):
    """A valid-looking config: every parameter scaled by 10**U(-k, k), some set to 0."""
    from cas_freq.core.parameters import PARAMETERS

    data = copy.deepcopy(base)
    data.pop("variants", None)
    k = rng.choice([1, 2, 3, 6])
    for key in PARAMETERS:
        path = tuple(key.split("."))
        try:
            value = get(data, path)
        except (KeyError, TypeError):
            continue
        from cas_freq.core.parameters import parse_value

        si = parse_value(key, value)
        if rng.random() < 0.1 and ("delay" in key or key.endswith(("Ki", "Kd", "ff_v", "ff_a"))):
            put(data, path, 0)
        else:
            value = si * 10.0 ** rng.uniform(-k, k)
            # a key whose datasheets use another unit needs one (the no-load speed)
            unit = PARAMETERS[key].unit if PARAMETERS[key].datasheet_unit else None
            put(data, path, f"{value!r} {unit}" if unit else value)
    return data


def finite_json(value):
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(finite_json(v) for v in value.values())
    if isinstance(value, list):
        return all(finite_json(v) for v in value)
    return True


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang


#: ``--save DIR``: where the workers (forked after it is set) write the configs that raised.
SAVE_DIR = None


def _save(text, detail):
    """Write a failing config and what it raised into :data:`SAVE_DIR`."""
    import hashlib

    folder = SAVE_DIR
    folder.mkdir(parents=True, exist_ok=True)
    name = hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()[:12]
    (folder / f"{name}.yaml").write_text(text, encoding="utf-8", errors="surrogateescape")
    (folder / f"{name}.txt").write_text(detail, encoding="utf-8")


def run_case(job):
    """Run one command on one config text in this worker: the outcome as a string."""
    command, text = job
    from cas_freq.cli import main

    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "config.yaml")
        with open(path, "w", encoding="utf-8", errors="surrogateescape") as file:
            file.write(text)
        argv = {"analyze": ["analyze", path, "--json"],
                "verify": ["verify", path, "--json"],
                "simulate": ["simulate", path, "--step", "10deg", "--json"]}[command]
        out, err = io.StringIO(), io.StringIO()
        signal.signal(signal.SIGALRM, _alarm)
        signal.alarm(HANG_S)
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = main(argv)
        except _Hang:
            return "hang", ""
        except SystemExit as exc:  # argparse's refusal
            code = exc.code
        except BaseException as exc:  # noqa: BLE001 - this is what is being counted
            import traceback

            if SAVE_DIR is not None:
                _save(text, traceback.format_exc())
            return "traceback", f"{type(exc).__name__}: {str(exc)[:200]}"
        finally:
            signal.alarm(0)
    stderr = err.getvalue()
    if "Traceback" in stderr:
        return "traceback", stderr[-300:]
    if code == 2:
        if stderr.count("\n") == 1 and stderr.endswith("\n"):
            return "exit 2", ""
        return "traceback", "exit 2 with " + repr(stderr[:300])
    if code in (0, 1):
        try:
            data = json.loads(out.getvalue(), parse_constant=lambda name: float(name))
        except ValueError:
            return "non-finite JSON", out.getvalue()[:200]
        if not finite_json(data):
            return "non-finite JSON", ""
        return f"exit {code}", ""
    return "traceback", f"exit {code}: {stderr[:200]}"


def check_typos(typos):
    """Typos a value string read as a number (another than the original's)."""
    from cas_freq.core.exceptions import CasFreqError
    from cas_freq.core.parameters import PARAMETERS, parse_value

    wrong = []
    for dotted, original, typo_text in typos:
        key = dotted.split(".", 2)[-1] if dotted.startswith("variants.") else dotted
        if key not in PARAMETERS:
            continue
        try:
            value = parse_value(key, typo_text)
        except CasFreqError:
            continue
        if value != parse_value(key, original):
            wrong.append((dotted, original, typo_text, value))
    return wrong


def requirement_typos(typos):
    """Typos of requirement bounds accepted with another value."""
    from cas_freq.config import read_config_file
    from cas_freq.config.requirement import convert_bound

    wrong = []
    for dotted, original, typo_text in typos:
        parts = dotted.split(".")
        if parts[0] != "requirements" or parts[-1] not in ("min", "max"):
            continue
        base = read_config_file(SHIPPED)["requirements"][int(parts[1])]["metric"]
        try:
            value = convert_bound(typo_text, base)
        except (ValueError, TypeError):
            continue
        if value != convert_bound(original, base):
            wrong.append((dotted, original, typo_text, value))
    return wrong


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mutated", type=int, default=5000)
    parser.add_argument("--extreme", type=int, default=2000)
    parser.add_argument("--commands", default="analyze",
                        help="comma list of analyze, verify, simulate (default analyze)")
    parser.add_argument("--seed", type=int, default=16)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--kinds", default="mutated,extreme",
                        help="which cases to run (all are drawn, so a seed gives the same cases)")
    parser.add_argument("--save", metavar="DIR",
                        help="write each config that raised, with its traceback, into DIR")
    parser.add_argument("--show", type=int, default=5, help="examples shown per bad outcome")
    args = parser.parse_args(argv)
    if args.quick:
        args.mutated, args.extreme = 200, 100
    if args.save:
        global SAVE_DIR
        SAVE_DIR = Path(args.save).resolve()
    rng = random.Random(args.seed)
    base_text = SHIPPED.read_text(encoding="utf-8")
    from cas_freq.config import read_config_file

    base = read_config_file(SHIPPED)  # as cas_freq reads it (YAML 1.2 scalars)
    cases, typos = [], []
    for _ in range(args.mutated):
        if rng.random() < 0.15:
            cases.append(("mutated", text_mutation(rng, base_text)))
            continue
        data = copy.deepcopy(base)
        mutate(rng, data, typos)
        cases.append(("mutated", yaml.safe_dump(data, allow_unicode=True, sort_keys=False)))
    for _ in range(args.extreme):
        data = extreme_config(rng, base)
        cases.append(("extreme", yaml.safe_dump(data, sort_keys=False)))
    # typos are also tried directly, many more of them
    for _ in range(20 * args.mutated // 100 + 400):
        path = rng.choice([p for p in leaf_paths(base) if isinstance(get(base, p), str)])
        made = typo(rng, get(base, path))
        if made:
            typos.append((".".join(map(str, path)), get(base, path), made[1]))
    wrong_typos = check_typos(typos) + requirement_typos(typos)

    for command in args.commands.split(","):
        started = time.time()
        counts, examples = {}, {}
        kinds = set(args.kinds.split(","))
        chosen = [case for case in cases if case[0] in kinds]
        jobs = [(command, text) for _, text in chosen]
        with multiprocessing.get_context("fork").Pool(args.workers, maxtasksperchild=200) as pool:
            for (kind, _), (outcome, detail) in zip(chosen, pool.imap(run_case, jobs, chunksize=4),
                                                    strict=True):
                counts.setdefault(kind, {}).setdefault(outcome, 0)
                counts[kind][outcome] += 1
                if outcome in ("traceback", "hang", "non-finite JSON"):
                    examples.setdefault(outcome, []).append(detail)
        print(f"\n{command}: {len(chosen)} configs in {time.time() - started:.0f} s")
        for kind, outcomes in counts.items():
            tried = sum(outcomes.values())
            print(f"  {kind:8s} tried {tried:5d}: clean exit 2 {outcomes.get('exit 2', 0)}, "
                  f"exit 0 {outcomes.get('exit 0', 0)}, exit 1 {outcomes.get('exit 1', 0)}, "
                  f"tracebacks {outcomes.get('traceback', 0)}, hangs {outcomes.get('hang', 0)}, "
                  f"non-finite JSON {outcomes.get('non-finite JSON', 0)}")
        for outcome, details in examples.items():
            for detail in details[: args.show]:
                print(f"    {outcome}: {detail}")
        sys.stdout.flush()
    print(f"\ntypo strings tried {len(typos)}, read as a different number {len(wrong_typos)}")
    for example in wrong_typos[: args.show]:
        print(f"    {example}")


if __name__ == "__main__":
    main()
