"""``cas-freq fit [CONFIG] --data FILE... --candidates FILE``: candidate structures, each
fitted to the same recordings through the nonlinear simulator and ranked side by side
(:mod:`cas_freq.studies.candidates`; docs/identification.md, "Candidates side by side")."""

from cas_freq.cli.common import column_option, selected_variants, write_and_print
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.output import angle
from cas_freq.report.outdir import check_output_dir
from cas_freq.report.studies import json_text
from cas_freq.studies.candidates import rank_candidates, ranking_text


def run_candidates(args):
    """Fit every candidate of ``args.candidates``, rank them, print, write ``-o DIR``
    (candidates.json and candidates.svg)."""
    if args.params:
        raise CasFreqError("--candidates and --params: give the models one way (a candidates "
                           "file lists each one's free keys)")
    if args.output is not None:
        check_output_dir(args.output, "-o")
    base = selected_variants(args.target, [args.variant] if args.variant else [],
                             args.overrides)[0]
    step = None if args.step is None else angle(args.step, "--step")
    ranking = rank_candidates(base, args.candidates, args.data, column_option(args), step,
                              args.channels)

    def files():
        from cas_freq.plots.common import svg_text
        from cas_freq.plots.recordings import candidates_figure

        figure = candidates_figure(ranking.recordings, ranking.fits,
                                   ranking.best or ranking.fits[0].name, ranking.output)
        return {"candidates.json": json_text(ranking.data), "candidates.svg": svg_text(figure)}

    return write_and_print(args, ranking.data, files, ranking_text)
