"""The design page's server: one HTML page, its script, and JSON endpoints.

Why this stack: the Python standard library's :class:`http.server.ThreadingHTTPServer` and
uPlot 1.6.32 (MIT, ~50 kB, a well-kept canvas plotting library: log axes, faceted x/y series
for the Nichols chart, draw hooks for the margins' markers) vendored in
``static/vendor/uplot`` (its README names the source commit and the files' sha256) and served
by this server from the installed package: nothing new to install, nothing fetched from a CDN
(the page works offline). The engine's latency per change (~70 ms for the frequency figures on
this machine, benchmarks/design.py) is far above a threaded standard-library server's overhead.

Endpoints (JSON in and out):

- ``GET /api/init?session=ID``: the config, the variant, the controls (:func:`controls`) and
  the session's values.
- ``POST /api/state`` ``{"session", "seq", "values": {key: text}, "step": "5deg",
  "nonlinear": bool}``: the figures of the config with ``values`` as ``--set`` overrides
  (:func:`cas_freq.design.compute.design_state`), or ``{"errors": {key: message}}`` for a
  value the config refuses (the session keeps its previous values). A request older than the
  session's newest (``seq``) is answered ``{"stale": true}`` without computing.
- ``POST /api/control`` ``{"key"}``: a control for one more numeric key of the config.
- ``POST /api/tune`` ``{"session", "candidates", "rounds"}``: ``cas-freq tune`` of the page's
  keys from the session's values: the tuned values and the Pareto front.
- ``POST /api/save`` ``{"session", "name", "file", "force"}``: the config with the session's
  values as a new variant (:func:`cas_freq.drive.variant_text.config_with_variant`, written
  atomically; the input config is never overwritten) and the ``cas-freq verify`` command
  that checks it.

Every session (an id the page makes) has its own values: two browsers are independent.
"""

import json
import shlex
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from urllib.parse import parse_qs, urlparse

from cas_freq.design.compute import CHOICES
from cas_freq.exceptions import CasFreqError

#: Largest request body accepted [bytes].
MAX_BODY = 1 << 20
#: Most sessions kept (the oldest is forgotten beyond).
MAX_SESSIONS = 64
#: The files of the page, served from the installed package.
STATIC = {"/": ("index.html", "text/html; charset=utf-8"),
          "/design.js": ("design.js", "text/javascript; charset=utf-8"),
          "/design.css": ("design.css", "text/css; charset=utf-8"),
          "/vendor/uplot/uPlot.iife.min.js": ("vendor/uplot/uPlot.iife.min.js",
                                              "text/javascript; charset=utf-8"),
          "/vendor/uplot/uPlot.min.css": ("vendor/uplot/uPlot.min.css", "text/css; charset=utf-8")}


class Session:
    """One page's state: its accepted values and the newest request it sent."""

    def __init__(self):
        self.values = {}
        self.extra = []  # controls the page added (POST /api/control)
        self.newest = -1
        self.newest_lock = threading.Lock()  # held for an instant: never behind a computation
        self.lock = threading.Lock()  # one computation of the session at a time


class Design:
    """The design of one config variant, shared by every session of the server.

    Parameters
    ----------
    config : str or Path
        The config file.
    variant : str
        The variant the page starts from.
    keys : sequence of str, optional
        The keys of the controls (default: tune's free keys).
    """

    def __init__(self, config, variant="base", keys=None):
        from cas_freq.config import load_variant
        from cas_freq.design.compute import controls

        self.config = Path(config)
        self.variant = variant
        self.loaded = load_variant(self.config, variant)
        self.controls = controls(self.loaded, keys)
        self.sessions = {}
        self.lock = threading.Lock()

    def session(self, name):
        """The session called ``name`` (made on first use)."""
        name = str(name or "default")[:64]
        with self.lock:
            if name not in self.sessions:
                if len(self.sessions) >= MAX_SESSIONS:
                    self.sessions.pop(next(iter(self.sessions)))
                self.sessions[name] = Session()
            return self.sessions[name]

    def init(self, name):
        """The page's start: config, variant, controls and the session's values."""
        from cas_freq.output import output_unit

        return {"config": str(self.config), "variant": self.variant,
                "controls": self.controls + self.session(name).extra,
                "values": self.session(name).values,
                "step": output_unit(self.loaded.params).example}

    def state(self, request):
        """Figures for ``request`` (see the module's ``POST /api/state``)."""
        from cas_freq.config import load_variant
        from cas_freq.design.compute import check_values, design_state

        session = self.session(request.get("session"))
        seq = int(request.get("seq", 0))
        values = {str(k): str(v).strip() for k, v in (request.get("values") or {}).items()}
        with session.newest_lock:
            session.newest = max(session.newest, seq)
        with session.lock:  # one computation per session at a time; a newer request wins
            if seq < session.newest:
                return {"stale": True, "seq": seq}
            errors = check_values(values, self.loaded.params)
            if errors:
                return {"errors": errors, "seq": seq}
            step_rad = self._step(request.get("step"))
            try:
                loaded = load_variant(self.config, self.variant, tuple(values.items()))
            except CasFreqError as exc:
                message = str(exc)  # the key it names: after the file's "--set ...:" part
                key = next((k for k in values if f": {k}:" in message
                            or message.startswith(f"{k}:")), None) or \
                    next((k for k in values if k in message), "_")
                return {"errors": {key: message}, "seq": seq}
            data = design_state(loaded, step_rad, bool(request.get("nonlinear", True)))
            session.values = values
            data["seq"] = seq
            return data

    def _step(self, text):
        if not text:
            return None
        from cas_freq.cli.common import output_step

        return output_step(str(text), "step", [self.loaded])

    def control(self, request):
        """The control of one more key (any numeric key of the config :func:`controls`
        accepts), added to the session's."""
        from cas_freq.design.compute import controls

        session = self.session(request.get("session"))
        key = str(request.get("key") or "").strip()
        (control,) = controls(self.loaded, [key])
        with session.lock:
            if all(item["key"] != key for item in self.controls + session.extra):
                session.extra.append(control)
        return control

    def tune(self, request):
        """``cas-freq tune`` of the page's keys from the session's values (the tune's default
        objective, bounds and search; ``candidates``/``rounds`` as its options): the tuned
        values and the Pareto front of bandwidth, phase margin and overshoot."""
        from cas_freq.config import load_variant
        from cas_freq.tuning.options import GLOBAL_COUNT, ROUNDS
        from cas_freq.tuning.run import tune_variant
        from cas_freq.tuning.summary import tune_dict

        session = self.session(request.get("session"))
        candidates, rounds = (int(default if request.get(name) is None else request[name])
                              for name, default in (("candidates", GLOBAL_COUNT),
                                                    ("rounds", ROUNDS)))
        if not (1 <= candidates <= 2000 and 0 <= rounds <= 20):
            raise CasFreqError(f"tune: candidates 1..2000 and rounds 0..20, got {candidates} "
                               f"and {rounds}")
        loaded = load_variant(self.config, self.variant, tuple(session.values.items()))
        # tune varies the loop parameters: not the sampling keys (static in a batch)
        free = ",".join(control["key"] for control in self.controls + session.extra
                        if not control["key"].startswith("sampling."))
        result = tune_variant(loaded, free, candidates=candidates, rounds=rounds)
        from cas_freq.fileio import json_ready

        data = json_ready(tune_dict(result, loaded.params.name, loaded.variant, 0.0))
        return {key: data[key] for key in ("objective", "feasible", "tuned", "pareto", "free",
                                           "candidates", "feasible_candidates")}

    def save(self, request):
        """Write the config with the session's values as variant ``name``."""
        from cas_freq.config import load_variant
        from cas_freq.drive.variant_text import config_with_variant, si_text, variant_entries
        from cas_freq.fileio import check_output_file, write_text_atomic
        from cas_freq.parameters import base_values

        session = self.session(request.get("session"))
        name = str(request.get("name") or "designed")
        values = dict(session.values)
        loaded = load_variant(self.config, self.variant, tuple(values.items()))
        got = {**base_values(loaded.params), **_sampling_values(loaded.params)}
        base = load_variant(self.config, self.variant)
        changed = {key: (got[key] if key in CHOICES else si_text(key, got[key], loaded.params),
                         "cas-freq design") for key in values}
        text, saved = config_with_variant(
            self.config, name, variant_entries(base, changed),
            f"cas-freq design from variant {self.variant}",
            {key: got[key] for key in values if not key.startswith("sampling.")},
            "the designed values", force=bool(request.get("force")), tolerance=1e-5)
        for key, value in _sampling_values(saved.params).items():  # what base_values lacks
            if key in values and value != got[key]:
                raise CasFreqError(f"{self.config}: variant {name!r} loads {key} = {value!r}, "
                                   f"not {got[key]!r}; the variants block was not read as "
                                   "expected")
        file = Path(request.get("file") or f"{self.config.stem}-{name}.yaml")
        if file.exists() and file.resolve() == self.config.resolve():
            raise CasFreqError(f"{file}: is the input config; the design page never "
                               "overwrites it (choose another file)")
        check_output_file(file, "file")
        write_text_atomic(file, text)
        command = f"cas-freq verify {shlex.quote(str(file))} --variant {shlex.quote(name)}"
        return {"written": str(file), "variant": name, "command": command}


def _sampling_values(params):
    """{key: value} of the sampling keys of ``params`` (rates [Hz] or None, the method's
    word), which :func:`cas_freq.parameters.base_values` (the loop parameters) leaves out."""
    sampling = params.sampling
    return {f"sampling.{name}": getattr(sampling, name)
            for name in (*sampling.rates, "method")}


class Handler(BaseHTTPRequestHandler):
    """Serves the page and the endpoints of :class:`Design` (``self.server.design``)."""

    protocol_version = "HTTP/1.1"

    def log_message(self, format, *args):  # noqa: A002 - the page's requests are not news
        pass

    def _send(self, status, body, content_type="application/json"):
        data = body if isinstance(body, bytes) else json.dumps(body).encode("utf-8")
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(data)

    def do_GET(self):  # noqa: N802 - http.server's name
        url = urlparse(self.path)
        if url.path in STATIC:
            name, content_type = STATIC[url.path]
            data = resources.files("cas_freq.design").joinpath("static", *name.split("/"))\
                .read_bytes()
            return self._send(200, data, content_type)
        if url.path == "/api/init":
            session = parse_qs(url.query).get("session", ["default"])[0]
            return self._send(200, self.server.design.init(session))
        return self._send(404, {"error": f"no such page: {url.path}"})

    def do_POST(self):  # noqa: N802
        url = urlparse(self.path)
        design = self.server.design
        actions = {"/api/state": design.state, "/api/save": design.save,
                   "/api/tune": design.tune, "/api/control": design.control}
        if url.path not in actions:
            return self._send(404, {"error": f"no such endpoint: {url.path}"})
        try:
            length = int(self.headers.get("Content-Length") or 0)
            if not 0 <= length <= MAX_BODY:
                raise CasFreqError(f"request of {length} bytes; at most {MAX_BODY}")
            request = json.loads(self.rfile.read(length) or b"{}")
            if not isinstance(request, dict):
                raise CasFreqError("expected a JSON object")
            return self._send(200, actions[url.path](request))
        except (CasFreqError, ValueError) as exc:  # bad input: said, never fatal
            return self._send(400, {"error": str(exc)})
        except Exception as exc:  # a bug in one request must not stop the server
            return self._send(500, {"error": f"{type(exc).__name__}: {exc}"})


def make_server(design, host="127.0.0.1", port=0):
    """A :class:`ThreadingHTTPServer` serving ``design`` on ``host``:``port`` (0: a free one)."""
    server = ThreadingHTTPServer((host, port), Handler)
    server.daemon_threads = True
    server.design = design
    return server


__all__ = ["Design", "Handler", "make_server"]
