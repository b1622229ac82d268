"""The operator page explains every figure a card's evidence can show."""

from __future__ import annotations

import re
from html.parser import HTMLParser

from sarmission.alerts.page import PAGE_HTML
from sarmission.mission.confirmation import Assessment


class _Terms(HTMLParser):
    """The text of every ``<dt>`` inside the page's help."""

    def __init__(self) -> None:
        super().__init__()
        self.in_help, self.in_term, self.terms = False, False, []

    def handle_starttag(self, tag, attrs):
        if tag == "details" and ("id", "help") in attrs:
            self.in_help = True
        elif tag == "dt" and self.in_help:
            self.in_term = True
            self.terms.append("")

    def handle_endtag(self, tag):
        if tag == "details":
            self.in_help = False
        elif tag == "dt":
            self.in_term = False

    def handle_data(self, data):
        if self.in_term:
            self.terms[-1] += data


def _shape(text: str) -> str:
    """A figure with its numbers blanked: ``drift 0.2 m/s`` -> ``drift # m/s``."""
    return re.sub(r"\d+(\.\d+)?", "#", " ".join(text.split()))


def test_every_figure_of_the_evidence_is_explained():
    parser = _Terms()
    parser.feed(PAGE_HTML)
    explained = {_shape(part) for term in parser.terms for part in term.split(", ")}
    everything = Assessment(
        "confirm",
        "",
        seen_s=2.1,
        sightings=20,
        seen_share=0.8,
        speed_m_s=0.2,
        size_m=0.6,
        score=0.84,
        extent_m=1.2,
        look_change=0.08,
    )
    shown = [_shape(part) for part in everything.summary().split(", ")]
    assert len(shown) == 8  # every optional figure is in the summary above
    assert [s for s in shown if s not in explained] == []
    assert "# % likely a person" in explained  # the confidence beside the score
