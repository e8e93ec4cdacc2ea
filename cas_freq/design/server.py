"""The design page's server: one HTML page, its script, and JSON endpoints.

Why this stack: the Python standard library's :class:`http.server.ThreadingHTTPServer` and
uPlot 1.6.32 (MIT, ~50 kB, a well-kept canvas plotting library: log axes, faceted x/y series
for the Nichols chart, draw hooks for the margins' markers) vendored in
``static/vendor/uplot`` (its README names the source commit and the files' sha256) and served
by this server from the installed package: nothing new to install, nothing fetched from a CDN
(the page works offline). The engine's latency per change (~70 ms for the frequency figures on
this machine, benchmarks/design.py) is far above a threaded standard-library server's overhead.

Endpoints (JSON in and out):

Every request passes :class:`cas_freq.design.guard.Guard` first (the served Host, no
cross-origin request, the per-launch token on ``/api/...``, JSON bodies); each body is read
into its model of :mod:`cas_freq.design.requests` (a wrong field: 400 naming it).

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
- ``POST /api/save`` ``{"session", "name", "file", "overwrite", "force"}``: the config with
  the session's values as a new variant (:func:`cas_freq.drive.variant_text.config_with_variant`,
  written atomically) and the ``cas-freq verify`` command that checks it. It writes only
  directly into the save folder (the config's, or ``--save-dir``), never the input config,
  and an existing file only with ``overwrite`` (409 without: the page asks the user first);
  see :func:`cas_freq.design.saving.save_target`.

Every session (an id the page makes) has its own values: two browsers are independent.
"""

import json
import shlex
import sys
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from urllib.parse import parse_qs, urlparse

from cas_freq.config import load_variant
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.fileio import json_ready, write_text_atomic
from cas_freq.core.output import output_step, output_unit
from cas_freq.core.parameters import base_values
from cas_freq.design import compute
from cas_freq.design.compute import CHOICES, check_values, controls
from cas_freq.design.guard import LOOPBACK_ADDRESSES, Guard, Refused, new_token
from cas_freq.design.requests import ControlRequest, SaveRequest, StateRequest, TuneRequest, parsed
from cas_freq.design.saving import save_target
from cas_freq.drive.variant_text import config_with_variant, si_text, variant_entries
from cas_freq.tuning.options import GLOBAL_COUNT, ROUNDS

#: Largest request body accepted [bytes].
MAX_BODY = 1 << 20
#: A connection's socket timeout [s]: a client that stops sending (a body shorter than its
#: Content-Length, an idle keep-alive connection) frees its thread after this.
READ_TIMEOUT_S = 10.0
#: Connections the listening socket queues while every thread is busy.
BACKLOG = 64
#: What a client that went away raises when its answer is written.
HUNG_UP = (BrokenPipeError, ConnectionResetError, ConnectionAbortedError, TimeoutError)
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
    save_dir : str or Path, optional
        The one folder saves write into (default: the config's folder).
    """

    def __init__(self, config, variant="base", keys=None, save_dir=None):
        self.config = Path(config)
        self.save_dir = Path(self.config.parent if save_dir is None else save_dir).resolve()
        if not self.save_dir.is_dir():
            raise CasFreqError(f"--save-dir {save_dir}: is not an existing folder")
        self.variant = variant
        self.loaded = load_variant(self.config, variant)
        self.controls = controls(self.loaded, keys)
        self.sessions = {}
        self.lock = threading.Lock()

    def session(self, name):
        """The session called ``name`` (made on first use)."""
        with self.lock:
            if name not in self.sessions:
                if len(self.sessions) >= MAX_SESSIONS:
                    self.sessions.pop(next(iter(self.sessions)))
                self.sessions[name] = Session()
            return self.sessions[name]

    def init(self, name):
        """The page's start: config, variant, controls and the session's values."""
        return {"config": str(self.config), "variant": self.variant,
                "save_dir": str(self.save_dir),
                "controls": self.controls + self.session(name).extra,
                "values": self.session(name).values,
                "step": output_unit(self.loaded.params).example}

    def state(self, request):
        """Figures for ``request`` (see the module's ``POST /api/state``)."""
        request = parsed(StateRequest, request)
        session = self.session(request.session)
        seq = request.seq
        values = {k: str(v).strip() for k, v in request.values.items()}
        with session.newest_lock:
            session.newest = max(session.newest, seq)
        with session.lock:  # one computation per session at a time; a newer request wins
            if seq < session.newest:
                return {"stale": True, "seq": seq}
            errors = check_values(values, self.loaded.params)
            if errors:
                return {"errors": errors, "seq": seq}
            step_rad = self._step(request.step)
            try:
                loaded = load_variant(self.config, self.variant, tuple(values.items()))
            except CasFreqError as exc:
                message = str(exc)  # the key it names: after the file's "--set ...:" part
                key = next((k for k in values if f": {k}:" in message
                            or message.startswith(f"{k}:")), None) or \
                    next((k for k in values if k in message), "_")
                return {"errors": {key: message}, "seq": seq}
            data = compute.design_state(loaded, step_rad, request.nonlinear)
            session.values = values
            data["seq"] = seq
            return data

    def _step(self, text):
        if not text:
            return None

        return output_step(str(text), "step", [self.loaded])

    def control(self, request):
        """The control of one more key (any numeric key of the config :func:`controls`
        accepts), added to the session's."""
        request = parsed(ControlRequest, request)
        session = self.session(request.session)
        key = request.key.strip()
        (control,) = controls(self.loaded, [key])
        with session.lock:
            if all(item["key"] != key for item in self.controls + session.extra):
                session.extra.append(control)
        return control

    def tune(self, request):
        """``cas-freq tune`` of the page's keys from the session's values (the tune's default
        objective, bounds and search; ``candidates``/``rounds`` as its options): the tuned
        values and the Pareto front of bandwidth, phase margin and overshoot."""
        from cas_freq.tuning.run import tune_variant
        from cas_freq.tuning.summary import tune_dict

        request = parsed(TuneRequest, request)
        session = self.session(request.session)
        candidates = GLOBAL_COUNT if request.candidates is None else request.candidates
        rounds = ROUNDS if request.rounds is None else request.rounds
        loaded = load_variant(self.config, self.variant, tuple(session.values.items()))
        # tune varies the loop parameters: not the sampling keys (static in a batch)
        free = ",".join(control["key"] for control in self.controls + session.extra
                        if not control["key"].startswith("sampling."))
        result = tune_variant(loaded, free, candidates=candidates, rounds=rounds)

        data = json_ready(tune_dict(result, loaded.params.name, loaded.variant, 0.0))
        return {key: data[key] for key in ("objective", "feasible", "tuned", "pareto", "free",
                                           "candidates", "feasible_candidates")}

    def save(self, request):
        """Write the config with the session's values as variant ``name`` (into the save
        folder only: :func:`cas_freq.design.saving.save_target`)."""
        request = parsed(SaveRequest, request)
        session = self.session(request.session)
        name = request.name
        file = save_target(request.file, self.save_dir, self.config,
                           f"{self.config.stem}-{name}.yaml", request.overwrite)
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
            "the designed values", force=request.force, tolerance=1e-5)
        for key, value in _sampling_values(saved.params).items():  # what base_values lacks
            if key in values and value != got[key]:
                raise CasFreqError(f"{self.config}: variant {name!r} loads {key} = {value!r}, "
                                   f"not {got[key]!r}; the variants block was not read as "
                                   "expected")
        write_text_atomic(file, text)
        command = f"cas-freq verify {shlex.quote(str(file))} --variant {shlex.quote(name)}"
        return {"written": str(file), "variant": name, "command": command}


def _sampling_values(params):
    """{key: value} of the sampling keys of ``params`` (rates [Hz] or None, the method's
    word), which :func:`cas_freq.core.parameters.base_values` (the loop parameters) leaves out."""
    sampling = params.sampling
    return {f"sampling.{name}": getattr(sampling, name)
            for name in (*sampling.rates, "method")}


class Handler(BaseHTTPRequestHandler):
    """Serves the page and the endpoints of :class:`Design` (``self.server.design``) to the
    requests ``self.server.guard`` lets through."""

    protocol_version = "HTTP/1.1"
    timeout = READ_TIMEOUT_S  # the socket's: a silent client frees its thread

    def log_message(self, format, *args):  # noqa: A002 - the page's requests are not news
        pass

    def _send(self, status, body, content_type="application/json"):
        data = body if isinstance(body, bytes) else json.dumps(body).encode("utf-8")
        try:
            self.send_response(status)
            self.send_header("Content-Type", content_type)
            self.send_header("Content-Length", str(len(data)))
            self.send_header("Cache-Control", "no-store")
            self.send_header("X-Content-Type-Options", "nosniff")
            self.send_header("X-Frame-Options", "DENY")
            if self.close_connection:
                self.send_header("Connection", "close")
            self.end_headers()
            self.wfile.write(data)
        except HUNG_UP:  # the client went away: nobody to answer
            self.close_connection = True

    def _guarded(self, method):
        """The URL when the guard serves the request, else None (the refusal answered)."""
        url = urlparse(self.path)
        try:
            self.server.guard.check(method, url.path, self.headers)
        except Refused as exc:
            self.close_connection = True
            self._send(exc.status, {"error": str(exc)})
            return None
        return url

    def do_GET(self):  # noqa: N802 - http.server's name
        url = self._guarded("GET")
        if url is None:
            return None
        if url.path in STATIC:
            name, content_type = STATIC[url.path]
            data = resources.files("cas_freq.design").joinpath("static", *name.split("/"))\
                .read_bytes()
            return self._send(200, data, content_type)
        if url.path == "/api/init":
            session = parse_qs(url.query).get("session", ["default"])[0][:64]
            return self._send(200, self.server.design.init(session))
        return self._send(404, {"error": f"no such page: {url.path}"})

    def do_POST(self):  # noqa: N802
        url = self._guarded("POST")
        if url is None:
            return None
        design = self.server.design
        actions = {"/api/state": design.state, "/api/save": design.save,
                   "/api/tune": design.tune, "/api/control": design.control}
        if url.path not in actions:
            return self._send(404, {"error": f"no such endpoint: {url.path}"})
        try:
            request = self._body()
        except TimeoutError:  # fewer bytes than Content-Length said: the connection is closed
            self.close_connection = True
            return self._send(408, {"error": f"the request body did not arrive within "
                                             f"{self.timeout:g} s"})
        except CasFreqError as exc:
            self.close_connection = True  # the unread rest of a refused body is not a request
            return self._send(400, {"error": str(exc)})
        try:
            return self._send(200, actions[url.path](request))
        except Refused as exc:
            return self._send(exc.status, {"error": str(exc)})
        except CasFreqError as exc:  # bad input: said, never fatal
            return self._send(400, {"error": str(exc)})
        except Exception as exc:  # a bug in one request must not stop the server
            return self._send(500, {"error": f"{type(exc).__name__}: {exc}"})

    def _body(self):
        """The request's JSON body (at most :data:`MAX_BODY` bytes).

        Raises
        ------
        CasFreqError
            A missing or bad Content-Length, a body that is not JSON or nests too deep.
        TimeoutError
            The body's bytes stopped arriving.
        """
        text = self.headers.get("Content-Length")
        try:
            length = int(text)
        except (TypeError, ValueError):
            raise CasFreqError(f"Content-Length {text!r}: expected the body's length in "
                               "bytes") from None
        if not 0 <= length <= MAX_BODY:
            raise CasFreqError(f"Content-Length {length}: expected 0..{MAX_BODY} bytes")
        data = self.rfile.read(length)
        if len(data) < length:  # the client closed its side early
            raise CasFreqError(f"the body ended after {len(data)} of {length} bytes")
        try:
            return json.loads(data or b"{}")
        except RecursionError:
            raise CasFreqError("the JSON body nests too deep") from None
        except (UnicodeDecodeError, ValueError) as exc:
            raise CasFreqError(f"the body is not JSON: {exc}") from None


class Server(ThreadingHTTPServer):
    """A threaded server whose listen queue holds :data:`BACKLOG` connections and whose
    clients' hang-ups are not errors."""

    request_queue_size = BACKLOG
    daemon_threads = True
    block_on_close = False

    def handle_error(self, request, client_address):
        """A client that went away is not news; anything else one line on stderr."""
        error = sys.exc_info()[1]
        if not isinstance(error, HUNG_UP):
            print(f"cas-freq design: error serving {client_address[0]}: "
                  f"{type(error).__name__}: {error}", file=sys.stderr, flush=True)


def make_server(design, host="127.0.0.1", port=0, token=None, read_timeout=READ_TIMEOUT_S):
    """A :class:`Server` serving ``design`` on ``host``:``port`` (0: a free one).

    Parameters
    ----------
    design : Design
        What the endpoints compute.
    host : str
        The address to listen on (``0.0.0.0``: every interface, any Host accepted).
    port : int
        The port (0: a free one).
    token : str, optional
        The per-launch token the API requires (default: a new random one); the page's URL is
        :func:`page_url`.
    read_timeout : float
        A connection's socket timeout [s].
    """
    handler = type("Handler", (Handler,), {"timeout": read_timeout})
    server = Server((host, port), handler)
    server.design = design
    server.guard = Guard(server.server_address[1], token or new_token(),
                         remote=host not in LOOPBACK_ADDRESSES)
    return server


def page_url(server):
    """The page's URL with its token, as ``cas-freq design`` prints it."""
    return f"http://127.0.0.1:{server.server_address[1]}/?token={server.guard.token}"


__all__ = ["Design", "Handler", "Server", "make_server", "page_url"]
