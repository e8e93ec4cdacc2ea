"""Results of the sign-off studies in the Python API: the worst case over the tolerances
(:meth:`cas_freq.api.Actuator.worst_case`) and candidate structures ranked against recordings
(:meth:`cas_freq.api.Actuator.rank_candidates`)."""

import dataclasses

from cas_freq.core.summary import Summary
from cas_freq.studies.candidates import ranking_text
from cas_freq.studies.worstcase import worst_case_text


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class WorstCase(Summary):
    """The worst case of each requirement's figure over the tolerance box
    (:meth:`Actuator.worst_case`).

    Attributes
    ----------
    data : dict
        The JSON of ``cas-freq worstcase --json``: ``box``, ``requirements`` (per requirement
        ``nominal``, ``worst``, ``at``, ``at_corner``, ``found_by``, ``worst_fails``),
        ``stability``, ``stability_margins``, ``search`` (the evaluations counted).
    """

    data: dict

    @property
    def requirements(self):
        """One dict per requirement searched, in the config's order."""
        return self.data["requirements"]

    @property
    def text(self):
        """The text ``cas-freq worstcase`` prints."""
        return worst_case_text(self.data)

    def _summary(self):
        rows = [(f"{r['id']} {r['metric']}",
                 ("not stable" if r["not_stable_or_missing"] else f"{r['worst']:.4g}")
                 + (" FAILS" if r["worst_fails"] else ""), "") for r in self.requirements]
        return f"worst found over {len(self.data['box'])} toleranced keys", rows

    def to_dict(self):
        """JSON-ready dict: the JSON of ``cas-freq worstcase --json``."""
        return self.data


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class CandidateRanking(Summary):
    """Candidate structures fitted to recordings and ranked
    (:meth:`Actuator.rank_candidates`).

    Attributes
    ----------
    ranking : cas_freq.studies.candidates.Ranking
        The fits (``ranking.fits``, best first), the recordings and the JSON-ready data.
    """

    ranking: object

    @property
    def rows(self):
        """One dict per candidate, best first: ``name``, ``rank``, ``plausibility``,
        ``flagged``, ``aicc``, ``delta_aicc``, ``rms_position_deg``, ``step`` figures, ..."""
        return self.ranking.data["ranking"]

    @property
    def best(self):
        """The best plausible, determined candidate's name, or None."""
        return self.ranking.best

    @property
    def text(self):
        """The table ``cas-freq fit --candidates`` prints."""
        return ranking_text(self.ranking.data)

    def _summary(self):
        rows = [(f"{row['rank']}. {row['name']}",
                 f"dAICc {row['delta_aicc']:.4g}, {row['plausibility']}"
                 + (", flagged" if row["flagged"] else ""), "") for row in self.rows]
        return f"{len(self.rows)} candidates; best plausible: {self.best or 'none'}", rows

    def to_dict(self):
        """JSON-ready dict: the JSON of ``cas-freq fit --candidates ... --json``."""
        return self.ranking.data

    def plot(self):
        """Each candidate's fitted step overlaid on the recordings, and the residuals.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from cas_freq.plots.recordings import candidates_figure

        r = self.ranking
        return candidates_figure(r.recordings, r.fits, r.best or r.fits[0].name, r.output)


__all__ = ["CandidateRanking", "WorstCase"]
