"""``cas-freq design``: a local interactive design page (:mod:`cas_freq.design.server`).

Prints the page's URL, with its per-launch token, as its first line; serves until Ctrl-C
(exit 130, as every command). The page saves only into the config's folder or ``--save-dir``.
"""

import sys

from cas_freq.cli.common import config_path, say_shipped_config
from cas_freq.core.exceptions import CasFreqError


def register(commands):
    """Add the ``design`` sub-parser."""
    parser = commands.add_parser(
        "design", help="interactive design page: change a gain, see margins, steps, verdicts",
        description="Serve a local page with a log slider and a typed entry per key (tune's "
        "free keys by default), grouped by loop; after each change it shows every loop's Bode "
        "with its crossovers and margins, T with the bandwidth and the requirement's line, the "
        "loop-at-a-time margins, the verdicts of the config's analyze-kind requirements, and "
        "the linear and nonlinear step, the previous state as a faint overlay. 'Save as "
        "variant' writes the config with a new variant into the config's folder (or --save-dir) "
        "and shows the verify command. Binds 127.0.0.1 unless --allow-remote; the API answers "
        "only the page opened from the printed URL (its token); stops with Ctrl-C.",
    )
    parser.add_argument("config", nargs="?", default=None, metavar="CONFIG",
                        help="config YAML (default: the shipped configs/qt_cas.yaml)")
    parser.add_argument("--variant", default="base", metavar="NAME",
                        help="the variant to start from (default: base)")
    parser.add_argument("--keys", metavar="KEY,KEY,...",
                        help="the keys with controls: any numeric key of the config, the sample "
                        "rates of a sampled variant's loops (default: the free keys of tune)")
    parser.add_argument("--port", type=int, default=8765, metavar="N",
                        help="TCP port (default 8765; 0: any free port)")
    parser.add_argument("--save-dir", metavar="DIR",
                        help="the folder the page's 'Save as variant' writes into (default: the "
                        "config's folder); it never writes elsewhere")
    parser.add_argument("--no-browser", action="store_true", help="do not open a browser")
    parser.add_argument("--allow-remote", action="store_true",
                        help="listen on every interface (0.0.0.0), not only 127.0.0.1: anyone "
                        "who reaches the port can run the model and write config files")
    parser.set_defaults(handler=run)


def run(args):
    """Serve the page until interrupted."""
    from cas_freq.design.server import Design, make_server, page_url

    if not 0 <= args.port <= 65535:
        raise CasFreqError(f"--port: must be 0..65535, got {args.port}")
    keys = None
    if args.keys is not None:  # each key checked with the config (a sample rate too)
        keys = [key.strip() for key in args.keys.split(",")]
        if not all(keys) or len(set(keys)) != len(keys):
            raise CasFreqError(f"--keys {args.keys!r}: expected KEY,KEY,... each once, e.g. "
                               "position_loop.Kp,current_loop.Kp")
    config = config_path(args.config)
    say_shipped_config(args.config)
    design = Design(config, args.variant, keys, args.save_dir)
    host = "0.0.0.0" if args.allow_remote else "127.0.0.1"
    try:
        server = make_server(design, host, args.port)
    except OSError as exc:
        raise CasFreqError(f"--port {args.port}: cannot listen on {host}: {exc.strerror}") \
            from None
    port = server.server_address[1]
    url = page_url(server)
    print(url, flush=True)
    if args.allow_remote:
        print(f"cas-freq design: warning: listening on every interface (port {port}); anyone "
              "who reaches it can run the model and write config files", file=sys.stderr,
              flush=True)
    if not args.no_browser:
        import webbrowser

        webbrowser.open(url)
    try:
        server.serve_forever(poll_interval=0.2)
    finally:
        server.server_close()
    return 0


__all__ = ["register", "run"]
