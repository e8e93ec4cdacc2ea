"""The design server refuses what a web page of another site, a rebound DNS name or a broken
client could make it do, as Jupyter's server does: each refusal from a real HTTP client
(``http.client`` or a raw socket) on loopback.

Most checks run against ``cas-freq design`` as the user starts it (a subprocess, on a copy of
the shipped config in a folder of its own, so that its save folder is a temporary one); the
thread and stderr checks against a server in this process (:func:`make_server` with a short
read timeout), whose threads and stderr the test can see.
"""

import contextlib
import http.client
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "configs" / "qt_cas.yaml"


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """(port, token, save folder, a file outside it) of a running ``cas-freq design``."""
    folder = tmp_path_factory.mktemp("design")
    save_dir = folder / "configs"
    save_dir.mkdir()
    config = save_dir / "axis.yaml"
    shutil.copy(SHIPPED, config)
    victim = folder / "victim.yaml"
    victim.write_text("precious: true\n", encoding="utf-8")
    process = subprocess.Popen(
        [sys.executable, "-m", "cas_freq", "design", str(config), "--no-browser", "--port",
         "0", "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=folder,
        env={**os.environ, "PYTHONPATH": str(ROOT)}, start_new_session=True)
    url = process.stdout.readline().strip()
    found = re.fullmatch(r"http://127\.0\.0\.1:(\d+)/\?token=([\w-]{32,})", url)
    try:
        assert found, (url, process.poll() is not None and process.stderr.read())
        yield int(found[1]), found[2], save_dir, victim
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.communicate()


def _ask(port, method, path, body=None, headers=None, host=None):
    """(status, JSON answer) of one request; ``body`` a dict (sent as JSON) or bytes."""
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
    try:
        data = body if isinstance(body, bytes) or body is None else json.dumps(body).encode()
        sent = {"Host": host or f"127.0.0.1:{port}", **(headers or {})}
        connection.request(method, path, body=data, headers=sent)
        response = connection.getresponse()
        text = response.read()
        kind = response.getheader("Content-Type", "")
        return response.status, json.loads(text) if kind.startswith("application/json") \
            else text
    finally:
        connection.close()


def _api(served, path, body, **headers):
    """(status, answer) of POST ``path`` as the page sends it: JSON with its token."""
    port, token = served[:2]
    return _ask(port, "POST", path, body, {"Content-Type": "application/json",
                                           "X-Cas-Freq-Token": token, **headers})


def test_a_cross_site_text_plain_save_of_any_file_is_refused_and_the_file_unchanged(served):
    # the attack as the issue reproduced it: a page of another site posts text/plain (no
    # CORS preflight) naming a file by absolute path; refused whatever else it gets right
    port, token, _, victim = served
    body = {"file": str(victim), "name": "x"}
    for headers in (
            {"Content-Type": "text/plain", "Origin": "http://evil.example"},
            {"Content-Type": "text/plain", "Origin": "http://evil.example",
             "X-Cas-Freq-Token": token},
            {"Content-Type": "application/json", "Origin": "http://evil.example",
             "X-Cas-Freq-Token": token},
            {"Content-Type": "application/json", "Sec-Fetch-Site": "cross-site",
             "X-Cas-Freq-Token": token}):
        status, answer = _ask(port, "POST", "/api/save", body, headers)
        assert status == 403, (headers, answer)
        assert "cross-" in answer["error"]
    assert victim.read_text(encoding="utf-8") == "precious: true\n"


def test_a_state_changing_request_needs_json_and_the_launch_token(served):
    port, token, _, _ = served
    for path in ("/api/state", "/api/save", "/api/tune", "/api/control"):
        status, answer = _ask(port, "POST", path, {}, {"Content-Type": "application/json"})
        assert status == 403 and "X-Cas-Freq-Token" in answer["error"], path
        wrong = token[:-1] + "AB"[token[-1] == "A"]  # one character off
        status, answer = _ask(port, "POST", path, {}, {"Content-Type": "application/json",
                                                       "X-Cas-Freq-Token": wrong})
        assert status == 403, path
        status, answer = _ask(port, "POST", path, {}, {"Content-Type": "text/plain",
                                                       "X-Cas-Freq-Token": token})
        assert status == 415 and "application/json" in answer["error"], path
    # the API's reads too (the config's path and the session's values are the user's)
    status, _ = _ask(port, "GET", "/api/init?session=a")
    assert status == 403
    status, answer = _ask(port, "GET", "/api/init?session=a", headers={
        "X-Cas-Freq-Token": token})
    assert status == 200 and answer["variant"] == "base"


def test_only_the_served_address_is_accepted_as_host(served):
    # DNS rebinding: evil.example resolving to 127.0.0.1 sends Host: evil.example
    port, token, _, _ = served
    for host in ("evil.example", f"evil.example:{port}", f"127.0.0.1:{port + 1}",
                 "127.0.0.1", f"localhost.evil.example:{port}"):
        status, answer = _ask(port, "GET", "/", host=host)
        assert status == 403 and "not this server's address" in answer["error"], host
        status, _ = _api(served, "/api/state", {}, Host=host)
        assert status == 403, host
    for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"[::1]:{port}",
                 f"LOCALHOST:{port}"):
        status, page = _ask(port, "GET", "/", host=host)
        assert status == 200 and b"design.js" in page, host
    # the page's own requests: same origin
    status, _ = _api(served, "/api/control", {"key": "position_loop.Kd"},
                     Origin=f"http://127.0.0.1:{port}", **{"Sec-Fetch-Site": "same-origin"})
    assert status == 200


@pytest.mark.parametrize("file, why", [
    ("{victim}", "saves only directly into"),  # an absolute path outside
    ("../victim.yaml", "saves only directly into"),  # a relative escape
    ("new/x.yaml", "saves only directly into"),  # a folder that would be made
    ("{save_dir}/../victim.yaml", "saves only directly into"),
    ("notes.txt", "ending in .yaml or .yml"),
    ("axis.yaml", "is the input config"),
])
def test_saves_go_only_into_the_save_folder(served, file, why):
    port, token, save_dir, victim = served
    asked = file.format(victim=victim, save_dir=save_dir)
    before = sorted(p.name for p in save_dir.parent.rglob("*"))
    status, answer = _api(served, "/api/save", {"name": "mine", "file": asked,
                                                "overwrite": True})
    assert status in (403, 409) and why in answer["error"], answer
    assert sorted(p.name for p in save_dir.parent.rglob("*")) == before
    assert victim.read_text(encoding="utf-8") == "precious: true\n"


def test_a_link_in_the_save_folder_is_not_followed(served):
    port, token, save_dir, victim = served
    link = save_dir / "link.yaml"
    link.symlink_to(victim)
    try:
        status, answer = _api(served, "/api/save", {"name": "mine", "file": "link.yaml",
                                                    "overwrite": True})
        assert status == 403 and "symbolic link" in answer["error"]
        assert victim.read_text(encoding="utf-8") == "precious: true\n"
    finally:
        link.unlink()


def test_an_existing_file_is_replaced_only_when_the_page_confirmed(served):
    port, token, save_dir, _ = served
    target = save_dir / "kept.yaml"
    target.write_text("mine: 1\n", encoding="utf-8")
    status, answer = _api(served, "/api/save", {"name": "mine", "file": "kept.yaml"})
    assert status == 409 and "exists" in answer["error"] and "confirm" in answer["error"]
    assert target.read_text(encoding="utf-8") == "mine: 1\n"
    status, answer = _api(served, "/api/save", {"name": "mine", "file": "kept.yaml",
                                                "overwrite": True})
    assert status == 200, answer
    assert answer["written"] == str(target.resolve())
    assert "variants:" in target.read_text(encoding="utf-8")
    # the default name, in the save folder
    status, answer = _api(served, "/api/save", {"name": "other"})
    assert status == 200 and answer["written"] == str((save_dir / "axis-other.yaml").resolve())


@pytest.mark.parametrize("path, body, field", [
    ("/api/state", {"values": "position_loop.Kp=3"}, "values"),
    ("/api/state", b'{"seq": 1e400}', "seq"),
    ("/api/state", {"seq": None}, "seq"),
    ("/api/state", {"seq": [1]}, "seq"),
    ("/api/state", {"values": {"position_loop.Kp": [3]}}, "values.position_loop.Kp"),
    ("/api/state", {"values": {"int_key": [3]}}, "values.int_key"),  # a key, not a branch
    ("/api/state", {"nonlinear": "yes"}, "nonlinear"),
    ("/api/state", {"sesion": "typo"}, "sesion"),
    ("/api/tune", b'{"candidates": 1e400}', "candidates"),
    ("/api/tune", {"rounds": 1.5}, "rounds"),
    ("/api/save", {"overwrite": "true"}, "overwrite"),
    ("/api/control", {"key": 7}, "key"),
])
def test_a_malformed_field_is_a_400_naming_it(served, path, body, field):
    status, answer = _api(served, path, body)
    assert status == 400, answer
    assert answer["error"].startswith(f"{field}: ") and "\n" not in answer["error"], answer


def test_bodies_that_are_not_requests_are_400s(served):
    deep = b"[" * 100_000 + b"]" * 100_000  # json's RecursionError, not a 500
    for body, words in ((deep, "nests too deep"), (b"{", "not JSON"),
                        (b"\xff\xfe", "not JSON"), (b"[1]", "JSON object")):
        status, answer = _api(served, "/api/state", body)
        assert status == 400 and words in answer["error"], (body[:10], answer)
    status, answer = _api(served, "/api/state", b"{}", **{"Content-Length": "x"})
    assert status == 400 and "Content-Length" in answer["error"]


# --- a server in this process: its threads, its stderr ------------------------------------


@pytest.fixture
def in_process(tmp_path):
    from cas_freq.design.server import Design, make_server

    server = make_server(Design(SHIPPED, save_dir=tmp_path), read_timeout=0.5)
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05},
                              daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()


def _serving_threads():
    return [t for t in threading.enumerate() if "process_request_thread" in t.name]


def test_a_body_shorter_than_its_length_frees_its_thread(in_process):
    port = in_process.server_address[1]
    token = in_process.guard.token
    clients = []
    for _ in range(8):
        client = socket.create_connection(("127.0.0.1", port), timeout=10)
        client.sendall(f"POST /api/state HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: "
                       f"application/json\r\nX-Cas-Freq-Token: {token}\r\nContent-Length: 100"
                       f"\r\n\r\n{{\"seq\": 1".encode())
        clients.append(client)
    for client in clients:  # each answered 408 after the read timeout, its connection closed
        answer = b""
        while chunk := client.recv(4096):
            answer += chunk
        assert answer.startswith(b"HTTP/1.1 408"), answer[:80]
        client.close()
    deadline = time.monotonic() + 5
    while _serving_threads() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _serving_threads() == []


def test_sixteen_clients_at_once_are_all_answered(in_process):
    port = in_process.server_address[1]
    token = in_process.guard.token
    answers = []

    def ask():
        answers.append(_ask(port, "GET", "/api/init?session=x",
                            headers={"X-Cas-Freq-Token": token})[0])

    threads = [threading.Thread(target=ask) for _ in range(16)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    assert answers == [200] * 16


def test_a_client_that_hung_up_is_no_traceback(in_process, capfd):
    port = in_process.server_address[1]
    token = in_process.guard.token
    for _ in range(3):  # hang up while the figures are computed
        client = socket.create_connection(("127.0.0.1", port), timeout=10)
        body = json.dumps({"values": {"position_loop.Kp": "3"}, "nonlinear": False}).encode()
        client.sendall(f"POST /api/state HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: "
                       f"application/json\r\nX-Cas-Freq-Token: {token}\r\nContent-Length: "
                       f"{len(body)}\r\n\r\n".encode() + body)
        client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        client.close()  # a reset, not a polite close
    status, _ = _ask(port, "GET", "/api/init?session=x", headers={"X-Cas-Freq-Token": token})
    assert status == 200
    time.sleep(1.0)  # the hung-up requests' answers are written (and fail) by now
    assert "Traceback" not in capfd.readouterr().err
