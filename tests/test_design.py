"""``cas-freq design``: the page's server answers as the commands do (issue 29).

The server runs as the user runs it (``python -m cas_freq design --no-browser --port 0``, a
subprocess), its URL read from its first stdout line; the figures it returns are compared with
what ``cas-freq analyze --set`` prints for the same values (the reference: the command's own
text, to its printed digits), and the saved variant with what ``cas-freq verify`` accepts.
"""

import contextlib
import hashlib
import html
import json
import os
import re
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import NamedTuple

import pytest
from clirun import run_cli
from conftest import chromium_or_skip

from cas_freq.core.figures import FIGURES

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "configs" / "qt_cas.yaml"
#: Ctrl-C must stop the server within this [s] (issue 29).
STOP_WITHIN_S = 1.0


class Served(NamedTuple):
    """A running ``cas-freq design``: its base URL, the token of the URL it printed, that URL
    (the page's), and the folder it saves into."""

    base: str
    token: str
    page: str
    save_dir: Path


def _start(*options, config=SHIPPED):
    """``cas-freq design CONFIG --no-browser --port 0 -q`` in a process group of its own
    (SIGINT at its default action, as from a terminal); returns (process, :class:`Served`
    read from its first line, the page's URL with its token)."""
    process = subprocess.Popen(
        [sys.executable, "-m", "cas_freq", "design", str(config), "--no-browser", "--port",
         "0", "-q", *options],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)}, start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    url = process.stdout.readline().strip()
    found = re.fullmatch(r"(http://127\.0\.0\.1:\d+/)\?token=([\w-]{32,})", url)
    assert found, (url, process.stderr.read() if process.poll() is not None else "")
    save_dir = Path(options[options.index("--save-dir") + 1]) if "--save-dir" in options \
        else Path(config).parent
    return process, Served(found[1], found[2], url, save_dir)


def _stop(process):
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGKILL)
    process.communicate()


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    process, served = _start("--save-dir", str(tmp_path_factory.mktemp("saved")))
    try:
        yield served
    finally:
        _stop(process)


def _post(served, path, body):
    """(HTTP status, JSON answer) of POST ``path``, as the page sends it (its token)."""
    request = urllib.request.Request(
        served.base + path.lstrip("/"), json.dumps(body).encode(),
        {"Content-Type": "application/json", "X-Cas-Freq-Token": served.token})
    try:
        with urllib.request.urlopen(request, timeout=60) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def _get(served, path):
    request = urllib.request.Request(served.base + path.lstrip("/"),
                                     headers={"X-Cas-Freq-Token": served.token})
    with urllib.request.urlopen(request, timeout=60) as response:
        return json.loads(response.read())


def _printed_phase_margins(*overrides):
    """{loop words: phase margin text} as ``cas-freq analyze --set ...`` prints them (the
    loop's own margin, not the loop-at-a-time one)."""
    argv = ["analyze", str(SHIPPED)]
    for item in overrides:
        argv += ["--set", item]
    code, out, _ = run_cli(argv)
    assert code == 0
    found = re.findall(r"^  (\w+ loop) L_\w+ .*\n(?:    .*\n)*?    phase margin +(\S+) deg",
                       out, flags=re.M)
    return dict(found)


def _state(url, session, seq, values, **options):
    return _post(url, "/api/state", {"session": session, "seq": seq, "values": values,
                                     "nonlinear": False, **options})


def test_a_gain_change_gives_the_phase_margin_analyze_prints(server):
    printed = _printed_phase_margins("position_loop.Kp=3")
    status, data = _state(server, "pm", 1, {"position_loop.Kp": "3"}, nonlinear=True,
                          step="5deg")
    assert status == 200 and "errors" not in data
    shown = {loop["words"]: loop["margins"]["text"]["phase_margin_deg"] for loop in data["loops"]}
    assert shown == printed and printed["position loop"] == "28.74"
    # the nonlinear step of 5 deg ends near 5 deg (the integrator removes the
    # error); the linear one too
    assert abs(data["step"]["nonlinear"]["y"][-1] - 5.0) < 0.05
    assert abs(data["step"]["linear"]["y"][-1] - 5.0) < 0.05
    # the verdicts are verify's: the bandwidth requirement's value is analyze's bandwidth
    (bandwidth,) = [v for v in data["verdicts"] if v["metric"] == "closed_loop.bandwidth_rad_s"]
    assert bandwidth["value"] == pytest.approx(data["closed_loop"]["bandwidth_rad_s"], rel=1e-12)
    assert data["closed_loop"]["required_bandwidth_rad_s"] == 300.0


def test_a_bad_value_is_named_with_its_range_and_the_server_goes_on(server):
    status, data = _state(server, "bad", 1, {"position_loop.Kp": "-3"})
    assert status == 200
    (message,) = data["errors"].values()
    assert list(data["errors"]) == ["position_loop.Kp"]
    assert "\n" not in message and "position_loop.Kp" in message and "-3" in message
    assert "1e-09..1e+09 A/rad" in message
    status, data = _state(server, "bad", 2, {"position_loop.Kp": "3 V"})
    assert "A/rad" in data["errors"]["position_loop.Kp"]
    status, data = _post(server, "/api/state", "not an object")
    assert status == 400 and "JSON object" in data["error"]
    # still answering, and the session kept no bad value
    status, data = _state(server, "bad", 3, {"position_loop.Kd": "0.03"})
    assert status == 200 and data["overrides"] == ["position_loop.Kd=0.03"]


def test_two_sessions_keep_two_states_and_a_stale_request_is_dropped(server):
    _state(server, "one", 1, {"position_loop.Kp": "3"})
    _state(server, "two", 1, {"position_loop.Kp": "12"})
    assert _get(server, "/api/init?session=one")["values"] == {"position_loop.Kp": "3"}
    assert _get(server, "/api/init?session=two")["values"] == {"position_loop.Kp": "12"}
    # a request older than the session's newest is not computed
    _state(server, "one", 5, {"position_loop.Kp": "4"})
    status, data = _state(server, "one", 4, {"position_loop.Kp": "5"})
    assert data == {"stale": True, "seq": 4}
    assert _get(server, "/api/init?session=one")["values"] == {"position_loop.Kp": "4"}


def test_save_as_variant_writes_a_config_verify_accepts(server):
    before = hashlib.sha256(SHIPPED.read_bytes()).hexdigest()
    _state(server, "save", 1, {"position_loop.Kp": "3", "position_loop.Ki": "50"})
    target = (server.save_dir / "designed.yaml").resolve()
    status, data = _post(server, "/api/save", {"session": "save", "name": "mine",
                                               "file": str(target)})
    assert status == 200, data
    assert data["command"] == f"cas-freq verify {target} --variant mine"
    code, out, err = run_cli(["verify", str(target), "--variant", "mine"])
    assert code in (0, 1), err  # verified (1 would be a failed requirement, not bad input)
    from cas_freq.config import load_variant

    loaded = load_variant(target, "mine")
    assert loaded.params.position_loop.Kp == pytest.approx(3.0)
    assert loaded.params.position_loop.Ki == pytest.approx(50.0)
    assert hashlib.sha256(SHIPPED.read_bytes()).hexdigest() == before
    # the input config, outside the save folder, is refused (tests/test_design_security.py
    # has every refusal), and so is an existing variant name
    status, data = _post(server, "/api/save", {"session": "save", "name": "mine2",
                                               "file": str(SHIPPED)})
    assert status == 403 and "saves only directly into" in data["error"]
    status, data = _post(server, "/api/save", {"session": "save", "name": "fitted",
                                               "file": "x.yaml"})
    assert status == 400 and "exists" in data["error"]


def _live_group(pgid):
    pids = []
    for entry in filter(str.isdigit, os.listdir("/proc")):
        try:
            fields = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] not in ("Z", "X"):
            pids.append(int(entry))
    return pids


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux's /proc")
def test_ctrl_c_stops_the_server_within_a_second_with_exit_130():
    process, served = _start("--allow-remote")
    try:
        assert "warning: listening on every interface" in process.stderr.readline()
        assert _get(served, "/api/init?session=x")["variant"] == "base"
        start = time.monotonic()
        os.killpg(process.pid, signal.SIGINT)
        code = process.wait(timeout=10)
        assert time.monotonic() - start < STOP_WITHIN_S
        assert code == 130
        assert _live_group(process.pid) == []
        assert process.stderr.read().strip() == "cas-freq design: interrupted"
    finally:
        _stop(process)


def test_the_server_binds_the_loopback_only_by_default():
    from cas_freq.design.server import Design, make_server

    server = make_server(Design(SHIPPED))
    try:
        assert server.server_address[0] == "127.0.0.1"
    finally:
        server.server_close()


@pytest.mark.slow  # a second browser start; the DevTools test below drives the page
def test_the_page_in_headless_chromium_shows_analyze_s_phase_margin(server, tmp_path):
    # The page's own start-up applies the URL's #key=value through its setValue path (the
    # sliders' and entries' path), requests the state and writes the margins table; Chromium
    # dumps the DOM after the page settles (virtual time waits for the page's requests).
    chromium = chromium_or_skip()
    done = subprocess.run(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=20000",
         "--dump-dom", f"{server.page}#position_loop.Kp=3"],
        capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-600:]
    shown = {name: html.unescape(value) for name, value in
             re.findall(r'id="pm-(\w+)">([^<]*)<', done.stdout)}
    printed = _printed_phase_margins("position_loop.Kp=3")
    assert shown == {"current_loop": printed["current loop"],
                     "position_loop": printed["position loop"]}
    assert 'id="entry-position_loop.Kp"' in done.stdout


@pytest.mark.parametrize("config, variant", [
    # the cascade's first analysis in a process takes ~2 s of CPU: with the slow tests
    pytest.param("cascade_axis", "base", marks=pytest.mark.slow),
    ("ball_screw", "base"), ("qt_cas", "sampled")])
def test_every_architecture_and_sampled_controllers_show_analyze_s_margins(config, variant):
    # the velocity loop's cascade, a linear output (mm) and sampled controllers: the page's
    # phase margins are analyze's printed ones, every loop
    from cas_freq.config import load_variant
    from cas_freq.design.compute import design_state

    path = ROOT / "configs" / f"{config}.yaml"
    data = design_state(load_variant(path, variant), nonlinear=False)
    code, out, _ = run_cli(["analyze", str(path), "--variant", variant])
    printed = dict(re.findall(r"^  (\w+ loop) L_\w+ .*\n(?:    .*\n)*?    phase margin +(\S+) deg",
                              out, flags=re.M))
    shown = {loop["words"]: loop["margins"]["text"]["phase_margin_deg"] for loop in data["loops"]}
    assert shown == printed and len(shown) == len(data["loops"]) >= 2
    assert data["step"]["unit"] == ("mm" if config == "ball_screw" else "deg")


class _DevTools:
    """The smallest client of Chromium's DevTools protocol over its WebSocket (RFC 6455 text
    frames, client-masked), standard library only: :meth:`evaluate` runs JavaScript in the
    page and returns its (awaited) value."""

    def __init__(self, ws_url):
        import base64
        import socket
        from urllib.parse import urlparse

        where = urlparse(ws_url)
        self.sock = socket.create_connection((where.hostname, where.port), timeout=60)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET {where.path} HTTP/1.1\r\nHost: {where.netloc}\r\n"
                           "Upgrade: websocket\r\nConnection: Upgrade\r\n"
                           f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n")
                          .encode())
        head = b""
        while b"\r\n\r\n" not in head:
            head += self.sock.recv(1)
        assert b" 101 " in head.split(b"\r\n")[0], head
        self.next_id = 0

    def _exactly(self, n):
        data = b""
        while len(data) < n:
            chunk = self.sock.recv(n - len(data))
            assert chunk, "DevTools closed the connection"
            data += chunk
        return data

    def _send(self, text):
        payload, mask = text.encode(), os.urandom(4)
        n = len(payload)
        head = bytes([0x81]) + (bytes([0x80 | n]) if n < 126 else
                                bytes([0x80 | 126]) + n.to_bytes(2, "big") if n < 65536 else
                                bytes([0x80 | 127]) + n.to_bytes(8, "big"))
        self.sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))

    def _receive(self):
        message = b""
        while True:
            first, second = self._exactly(2)
            n = second & 0x7F
            if n == 126:
                n = int.from_bytes(self._exactly(2), "big")
            elif n == 127:
                n = int.from_bytes(self._exactly(8), "big")
            message += self._exactly(n)
            if first & 0x80:  # the final fragment
                return json.loads(message)

    def evaluate(self, expression):
        self.next_id += 1
        self._send(json.dumps({"id": self.next_id, "method": "Runtime.evaluate", "params": {
            "expression": expression, "awaitPromise": True, "returnByValue": True}}))
        while True:
            answer = self._receive()
            if answer.get("id") == self.next_id:
                assert "result" in answer, answer
                result = answer["result"]
                assert "exceptionDetails" not in result, result
                return result["result"].get("value")


def test_moving_a_gain_in_chromium_shows_analyze_s_phase_margin_and_undo_goes_back(
        server, tmp_path):
    # The page in a real browser, driven through its own function casDesign.setValue (what
    # the sliders and entries call): three quick moves of a gain (debounced: one request, the
    # last value), then undo (back to before the moves); each time the phase margin the page
    # shows is what `cas-freq analyze --set` prints for that gain.
    chromium = chromium_or_skip()
    browser = subprocess.Popen(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         f"--user-data-dir={tmp_path / 'profile'}", "--remote-debugging-port=0",
         server.page], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        start_new_session=True)
    try:
        port = None
        deadline = time.monotonic() + 60
        while port is None:
            line = browser.stderr.readline()
            assert line and time.monotonic() < deadline, "Chromium gave no DevTools address"
            found = re.search(r"DevTools listening on ws://127\.0\.0\.1:(\d+)/", line)
            port = found and found.group(1)
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=30) as r:
            (page,) = [t for t in json.loads(r.read()) if t["type"] == "page"]
        tools = _DevTools(page["webSocketDebuggerUrl"])
        while True:  # until the page has loaded (its first state shown)
            try:
                tools.evaluate("new Promise(r => { const wait = () => window.casDesign ? "
                               "casDesign.ready.then(() => r(1)) : setTimeout(wait, 50); "
                               "wait(); })")
                break
            except AssertionError as exc:  # the blank page replaced by the design page
                assert "context was destroyed" in str(exc) and time.monotonic() < deadline
        # the figures are uPlot charts (served by the page's server, no other host): five of
        # them, each a canvas with the state's curves in it
        figures = tools.evaluate(
            "(() => { const c = casDesign.charts, s = casDesign.state();"
            " const m = c.magnitude.ctx.getImageData(0, 0, c.magnitude.ctx.canvas.width,"
            "  c.magnitude.ctx.canvas.height).data; let blue = 0;"
            " for (let i = 0; i < m.length; i += 4) blue += Math.abs(m[i] - 31) < 40 &&"
            "  Math.abs(m[i + 1] - 119) < 40 && Math.abs(m[i + 2] - 180) < 40;"
            " return [document.querySelectorAll('#figures .uplot').length,"
            "  document.querySelectorAll('#figures .uplot canvas').length,"
            "  Object.keys(c).sort(), c.magnitude.series.slice(1).map(x => x.label),"
            "  c.magnitude.data[1][0].length, s.omega_rad_s.length, blue,"
            "  c.step.series.slice(1).map(x => x.label),"
            "  performance.getEntriesByType('resource').map(e => e.name)]; })()")
        count, canvases, names, labels, points, omega, blue, step, loaded = figures
        assert count == canvases == len(names) == 5
        assert names == ["closed", "magnitude", "nichols", "phase", "step"]
        assert labels == ["L_i (broken at the voltage)", "L_p (broken at the current command)"]
        assert points == omega > 100 and blue > 200  # L_i's curve drawn, in its colour
        assert step == ["linear", "nonlinear"]
        assert {name.rsplit("/", 3)[-1] for name in loaded} >= {
            "uPlot.iife.min.js", "uPlot.min.css", "design.js", "design.css"}
        assert all(name.startswith(server.base) for name in loaded), loaded
        shown = tools.evaluate(
            "Promise.all(['5', '4', '3'].map(v => casDesign.setValue('position_loop.Kp', v)))"
            ".then(() => [document.getElementById('pm-position_loop').textContent,"
            " document.getElementById('entry-position_loop.Kp').value,"
            " document.body.dataset.seq])")
        assert shown[:2] == [_printed_phase_margins("position_loop.Kp=3")["position loop"], "3"]
        seq = int(shown[2])
        undone = tools.evaluate(
            "casDesign.undo().then(() => [document.getElementById('pm-position_loop')"
            ".textContent, document.body.dataset.seq])")
        # the three quick moves of one key are one gesture (a slider drag): undo goes back to
        # before it, the config's own gain
        assert undone[0] == _printed_phase_margins()["position loop"]
        assert int(undone[1]) == seq + 1  # one request for the three moves, one for undo
        # a bad value: the config's one-line error next to the field, the figures kept
        shown = tools.evaluate(
            "casDesign.setValue('position_loop.Kp', '-3').then(() => ["
            "document.getElementById('error-position_loop.Kp').textContent,"
            " document.getElementById('pm-position_loop').textContent])")
        assert shown[0].startswith("position_loop.Kp: must be 0 or within 1e-09..1e+09 A/rad")
        assert "'-3'" in shown[0] and shown[1] == undone[0]
        # the previous state faint behind, and compare with the variant: each loop's
        # magnitude and phase once more, dashed
        faint, dashed = tools.evaluate(
            "casDesign.setValue('position_loop.Kp', '3').then(() => {"
            " document.getElementById('compare').checked = true; return casDesign.compare(); })"
            ".then(() => [casDesign.charts.magnitude.series.filter(s => s.alpha < 1)"
            " .map(s => s.label), ['magnitude', 'phase'].map(n =>"
            " casDesign.charts[n].series.filter(s => s.dash && s.dash.length).length)])")
        assert faint == ["L_i previous", "L_p previous"] and dashed == [2, 2]
        # tune from here (a small search): a row per Pareto point and the tuned row, a dot
        # per point
        rows, dots, front = tools.evaluate(
            "casDesign.tune({candidates: 12, rounds: 0}).then(() => ["
            " document.querySelectorAll('#tune-table tr').length,"
            " casDesign.charts.pareto.data[1][0].length,"
            " document.getElementById('tune-status').textContent])")
        assert rows == dots + 2 and "of 13 candidates feasible" in front
        # a key at zero (the base's gear backlash): its slider starts at zero, then runs
        # log over the table's 1e-12..1 rad; the slider's end shows the table's bound
        ends = tools.evaluate(
            "(() => { document.getElementById('add-key').value = 'gear.backlash';"
            " return casDesign.addKey(); })().then(() => {"
            " const c = casDesign.slider.controls().find(c => c.key === 'gear.backlash');"
            " const {toSlider, fromSlider} = casDesign.slider;"
            " const slider = document.getElementById('slider-gear.backlash');"
            " return [slider.min, slider.max, slider.value,"
            "  [0, 1, 1000].map(p => fromSlider(c, p)), toSlider(c, 1e-6),"
            "  document.getElementById('entry-gear.backlash').value]; })")
        assert ends[:3] == ["0", "1000", "0"] and ends[5] == "0"
        assert ends[3] == [0, pytest.approx(1e-12), pytest.approx(1.0)]
        assert ends[4] == 1 + round(999 * 0.5)  # 1e-6 rad: half-way along the 12 decades
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(browser.pid, signal.SIGKILL)
        browser.communicate()


def test_analyze_without_the_hinge_scan_gives_every_other_figure_unchanged():
    # what the page skips per change: a loaded variant's stable hinge-stiffness scan; every
    # other figure is analyze's (the two analyses compared field by field)
    import dataclasses

    from cas_freq.analysis import analyze
    from cas_freq.config import load_variant

    loaded = load_variant(SHIPPED, "loaded")
    full, quick = analyze(loaded), analyze(loaded, hinge_range=False)
    assert full.drivetrain.stable_hinge_stiffness_n_m_rad[0] is not None
    assert quick.drivetrain.stable_hinge_stiffness_n_m_rad is None
    assert dataclasses.replace(full.drivetrain, stable_hinge_stiffness_n_m_rad=None) == \
        quick.drivetrain
    for name in ("current_loop", "position_loop", "closed_loop", "stability"):
        assert getattr(full, name) == getattr(quick, name)
    assert [n for n in full.notes if "load spring" not in n] == list(quick.notes)


def test_tune_from_here_returns_feasible_values_and_a_pareto_front(server):
    # a small search (the tune's own code; its figures are tune's tests'): the tuned values
    # are of the page's keys, within tune's default range around the session's values, and
    # each Pareto row carries the three trade-off figures
    _state(server, "tune", 1, {"position_loop.Kp": "3"})
    status, data = _post(server, "/api/tune", {"session": "tune", "candidates": 16,
                                               "rounds": 0})
    assert status == 200, data
    assert set(data["tuned"]["values"]) == {"position_loop.Kp", "position_loop.Ki",
                                            "position_loop.Kd"}
    assert 3.0 / 4 <= data["tuned"]["values"]["position_loop.Kp"] <= 3.0 * 4
    assert data["candidates"] == 16 + 1  # the search's 16 and the session's own values
    for row in data["pareto"]:
        assert {"closed_loop.bandwidth_rad_s", "position_loop.phase_margin_deg",
                "step.overshoot_pct"} <= set(row)
    status, data = _post(server, "/api/tune", {"session": "tune", "candidates": 0})
    assert status == 400 and "candidates" in data["error"]


def test_the_limited_spans_of_the_step_are_the_runs_of_the_clamp_flags():
    # worked by hand: flags 0 1 1 0 0 1 0 1 at t = 0..7 are clamped over [1, 2], [5, 5], [7, 7]
    import numpy as np

    from cas_freq.design.compute import limited_spans

    t = np.arange(8.0)
    assert limited_spans(t, [0, 1, 1, 0, 0, 1, 0, 1]) == [(1.0, 2.0), (5.0, 5.0), (7.0, 7.0)]
    assert limited_spans(t, [0] * 8) == []
    assert limited_spans(t, [1] * 8) == [(0.0, 7.0)]


def test_a_key_added_to_a_session_gets_its_control_there_only(server):
    status, control = _post(server, "/api/control", {"session": "add", "key": "current_loop.Kp"})
    assert status == 200
    assert control["group"] == "current_loop" and control["unit"] == "V/A"
    # tune's default range around the config's value, within the parameter table's range
    assert control["lower"] == pytest.approx(control["value"] / 4)
    assert control["upper"] == pytest.approx(control["value"] * 4)
    keys = [c["key"] for c in _get(server, "/api/init?session=add")["controls"]]
    assert keys[-1] == "current_loop.Kp"
    assert "current_loop.Kp" not in [c["key"] for c in _get(server, "/api/init?session=other")
                                     ["controls"]]
    status, data = _post(server, "/api/control", {"session": "add", "key": "motor.X"})
    assert status == 400 and "motor.X" in data["error"] and "\n" not in data["error"]


def test_a_sample_rate_has_a_control_and_multirate_errors_name_it():
    # the server's Design without HTTP (the endpoints call these methods): a sampled
    # variant's position-loop rate, its phase margin as analyze --set prints it, and a rate
    # that is not the current loop's divided by an integer refused naming the key
    from cas_freq.design.server import Design

    design = Design(SHIPPED, "sampled", ["position_loop.Kp", "sampling.position_loop"])
    assert design.controls[1]["value"] == 2500.0 and design.controls[1]["unit"] == "Hz"
    data = design.state({"session": "s", "seq": 1, "nonlinear": False,
                         "values": {"sampling.position_loop": "5 kHz"}})
    code, out, _ = run_cli(["analyze", str(SHIPPED), "--variant", "sampled", "--set",
                            "sampling.position_loop=5 kHz"])
    printed = dict(re.findall(r"^  (\w+ loop) L_\w+ .*\n(?:    .*\n)*?    phase margin +(\S+) deg",
                              out, flags=re.M))
    assert {loop["words"]: loop["margins"]["text"]["phase_margin_deg"]
            for loop in data["loops"]} == printed
    data = design.state({"session": "s", "seq": 2, "nonlinear": False,
                         "values": {"sampling.position_loop": "3 kHz"}})
    assert "multirate must be exact" in data["errors"]["sampling.position_loop"]
    from cas_freq.core.exceptions import ConfigError

    with pytest.raises(ConfigError, match="continuously"):
        Design(SHIPPED, "base", ["sampling.position_loop"])


def test_concurrent_sessions_get_their_own_answers(server):
    # four browsers at once (threads), two gains each: every answer is the one its values give
    # alone (the sequential answers of the same values are the reference)
    from concurrent.futures import ThreadPoolExecutor

    gains = ["2", "3", "4", "5"]
    alone = {kp: _state(server, f"alone-{kp}", 1, {"position_loop.Kp": kp})[1]
             for kp in gains}

    def ask(index):
        kp = gains[index % len(gains)]
        status, data = _state(server, f"busy-{index}", 1, {"position_loop.Kp": kp})
        return kp, data

    with ThreadPoolExecutor(4) as pool:
        answers = list(pool.map(ask, range(8)))
    for kp, data in answers:
        assert data["loops"] == alone[kp]["loops"] and data["overrides"] == [
            f"position_loop.Kp={kp}"]


def test_a_port_in_use_or_out_of_range_is_bad_input():
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        code, out, err = run_cli(["design", str(SHIPPED), "--no-browser", "--port", str(port)])
    assert code == 2 and out == ""
    assert err.startswith(f"cas-freq design: error: --port {port}: cannot listen on 127.0.0.1")
    code, _, err = run_cli(["design", str(SHIPPED), "--no-browser", "--port", "70000"])
    assert code == 2 and "--port: must be 0..65535, got 70000" in err


def test_keys_that_cannot_have_a_control_are_bad_input():
    code, _, err = run_cli(["design", str(SHIPPED), "--no-browser", "--port", "0", "--keys",
                            "position_loop.Kp,motor.X"])
    assert code == 2 and err.count("\n") == 1 and "motor.X" in err
    code, _, err = run_cli(["design", str(SHIPPED), "--no-browser", "--port", "0", "--keys",
                            "position_loop.Kp,,"])
    assert code == 2 and "expected KEY,KEY" in err
    code, _, err = run_cli(["design", str(SHIPPED), "--no-browser", "--port", "0", "--keys",
                            "sampling.current_loop"])
    assert code == 2 and "continuously" in err


def test_the_page_and_its_scripts_reference_no_other_host(server):
    # the page works offline: every file it loads is one the server serves from the package
    # (the plots' library, uPlot, vendored), and no served file names another host (the only
    # URL in them is the licence banner comment opening uPlot's file: a credit, not a load)
    from cas_freq.design.server import STATIC

    with urllib.request.urlopen(server.base, timeout=60) as response:
        page = response.read().decode()
    loads = re.findall(r'(?:src|href)="([^"]*)"', page)
    assert sorted("/" + name for name in loads) == sorted(path for path in STATIC if path != "/")
    for path in STATIC:
        with urllib.request.urlopen(server.base + path.lstrip("/"), timeout=60) as response:
            assert response.status == 200
            text = response.read().decode()
        if path.endswith("uPlot.iife.min.js"):
            banner = "/*! https://github.com/leeoniya/uPlot (v1.6.32) */\n"
            assert text.startswith(banner)
            text = text[len(banner):]
        assert re.findall(r"https?://[^\s\"'`)]*", text) == [], path


def test_the_vendored_plot_library_is_the_recorded_release():
    # uPlot's files are the release its README records (version, commit, sha256 per file),
    # unchanged
    folder = ROOT / "cas_freq" / "design" / "static" / "vendor" / "uplot"
    note = (folder / "README.md").read_text(encoding="utf-8")
    recorded = dict(re.findall(r"^\| `([^`]+)` \| `[^`]+` \| `([0-9a-f]{64})` \|$", note,
                               flags=re.M))
    assert set(recorded) == {"uPlot.iife.min.js", "uPlot.min.css", "LICENSE"}
    for name, digest in recorded.items():
        assert hashlib.sha256((folder / name).read_bytes()).hexdigest() == digest, name
    assert "1.6.32" in note and "dd3ffc568903c905ae5ba8d310e37216fd597404" in note
    assert "(v1.6.32)" in (folder / "uPlot.iife.min.js").read_text(encoding="utf-8")[:60]
    assert (folder / "LICENSE").read_text(encoding="utf-8").startswith("The MIT License")


def _printed(argv):
    """({loop words: phase margin text}, bandwidth text) as ``cas-freq analyze`` prints them."""
    code, out, _ = run_cli(["analyze", *argv])
    assert code == 0
    margins = dict(re.findall(
        r"^  (\w+ loop) L_\w+ .*\n(?:    .*\n)*?    phase margin +(\S+) deg", out, flags=re.M))
    label = re.escape(FIGURES["closed_loop.bandwidth_rad_s"].label)  # the figure table's
    (bandwidth,) = re.findall(rf"^    {label} +(\S+) rad/s", out, flags=re.M)
    return margins, bandwidth


def test_a_sampled_variant_s_discretisation_is_a_choice_that_moves_the_figures_as_set_does(
        tmp_path):
    # sampling.method of the sampled variant: a choice (backward | tustin) among the default
    # controls; tustin's figures are those `analyze --set sampling.method=tustin` prints
    # (the reference: the command's text, to its printed digits), and differ from backward's
    from cas_freq.config import load_variant
    from cas_freq.design.server import Design

    design = Design(SHIPPED, "sampled", save_dir=tmp_path)
    (choice,) = [c for c in design.controls if c["key"] == "sampling.method"]
    assert choice["choices"] == ["backward", "tustin"] and choice["value"] == "backward"
    shown = {}
    for seq, method in enumerate(("backward", "tustin")):
        data = design.state({"session": "m", "seq": seq, "nonlinear": False,
                             "values": {"sampling.method": method}})
        shown[method] = ({loop["words"]: loop["margins"]["text"]["phase_margin_deg"]
                          for loop in data["loops"]}, data["closed_loop"]["bandwidth_text"])
        assert shown[method] == _printed([str(SHIPPED), "--variant", "sampled", "--set",
                                          f"sampling.method={method}"])
    assert shown["tustin"] != shown["backward"]
    # a word it does not take: analyze --set's message, next to the field
    data = design.state({"session": "m", "seq": 5, "values": {"sampling.method": "zoh"}})
    assert data["errors"] == {"sampling.method": "sampling.method: must be one of 'backward' "
                                                 "or 'tustin', got 'zoh'"}
    # saved as a variant with a changed rate: both load back (the sampling keys are not loop
    # parameters: the save checks them itself); tune varies the numbers only
    design.state({"session": "m", "seq": 6, "nonlinear": False, "values": {
        "sampling.method": "tustin", "sampling.position_loop": "5 kHz"}})
    saved = design.save({"session": "m", "name": "tustin", "file": str(tmp_path / "t.yaml")})
    sampling = load_variant(saved["written"], "tustin").params.sampling
    assert (sampling.method, sampling.position_loop) == ("tustin", 5000.0)
    # tune varies the loop parameters, not the sampling keys (static for its batch)
    design = Design(SHIPPED, "sampled", ["position_loop.Kp", "sampling.position_loop",
                                         "sampling.method"])
    design.state({"session": "t", "seq": 1, "nonlinear": False,
                  "values": {"sampling.method": "tustin"}})
    tuned = design.tune({"session": "t", "candidates": 3, "rounds": 0})
    assert [item["key"] for item in tuned["free"]] == ["position_loop.Kp"]
    # a continuous variant has no discretisation to choose
    assert "sampling.method" not in [c["key"] for c in Design(SHIPPED).controls]
    code, _, err = run_cli(["design", str(SHIPPED), "--no-browser", "--port", "0", "--keys",
                            "sampling.method"])
    assert code == 2 and "sampling.method: the variant's controllers are continuous" in err


def test_a_key_at_zero_gets_a_slider_over_the_table_s_range_with_zero_on_it():
    # tune's range around the value (x/4..x4) is empty at zero: the slider spans the
    # parameter table's non-zero magnitudes instead, zero at its start, or at its centre for
    # a key that also takes negative values (the hinge spring); a negative value gets a log
    # slider on its own side of zero. The bounds are the table's (cas_freq/core/parameter_keys.py)
    from cas_freq.config import load_variant
    from cas_freq.design.compute import controls

    loaded = load_variant(SHIPPED, "base", (("position_loop.Kd", "0"),))
    kd, backlash, hinge = controls(loaded, ["position_loop.Kd", "gear.backlash",
                                            "load.hinge_stiffness"])
    assert (kd["value"], kd["slider"], kd["lower"], kd["upper"]) == (0.0, "zero-log", 1e-9, 1e9)
    assert (backlash["slider"], backlash["lower"], backlash["upper"]) == ("zero-log", 1e-12, 1.0)
    assert (hinge["slider"], hinge["lower"], hinge["upper"]) == ("signed-log", 1e-12, 1e9)
    loaded = load_variant(SHIPPED, "base", (("load.hinge_stiffness", "-50"),))
    (hinge,) = controls(loaded, ["load.hinge_stiffness"])
    assert (hinge["slider"], hinge["sign"], hinge["lower"], hinge["upper"]) == (
        "log", -1.0, 12.5, 200.0)


def test_a_session_computes_its_newest_request_only_while_one_is_in_flight(monkeypatch):
    # latest wins: while a session's computation runs, its newer requests wait without
    # computing, and when it ends only the newest of them is computed (the others are
    # answered stale); another session is computed meanwhile. The engine is replaced by a
    # recorder that holds session "a"'s first computation until released.
    import threading

    from cas_freq.design import compute
    from cas_freq.design.server import Design

    release, computed = threading.Event(), []

    def recorded(loaded, step_rad=None, nonlinear=True):
        computed.append(dict(loaded.overrides))
        if dict(loaded.overrides) == {"position_loop.Kp": "1"}:
            assert release.wait(30)
        return {}

    monkeypatch.setattr(compute, "design_state", recorded)
    design = Design(SHIPPED)
    answers = {}

    def ask(session, seq, kp=None):
        answers[session, seq] = design.state({"session": session, "seq": seq, "values": {
            "position_loop.Kp": kp or str(seq)}})

    first = threading.Thread(target=ask, args=("a", 1))
    first.start()
    while not computed:
        time.sleep(0.005)
    later = [threading.Thread(target=ask, args=("a", seq)) for seq in (2, 3, 4)]
    for thread in later:
        thread.start()
    while design.session("a").newest != 4:
        time.sleep(0.005)
    ask("b", 1, "7")  # another session is not behind session a's computation
    assert answers["b", 1] == {"seq": 1} and len(computed) == 2
    release.set()
    for thread in (first, *later):
        thread.join(30)
    assert computed == [{"position_loop.Kp": "1"}, {"position_loop.Kp": "7"},
                        {"position_loop.Kp": "4"}]
    assert answers["a", 1] == {"seq": 1} and answers["a", 4] == {"seq": 4}
    assert answers["a", 2] == {"stale": True, "seq": 2}
    assert answers["a", 3] == {"stale": True, "seq": 3}
