"""A griffe extension for the API reference (mkdocs.yml, mkdocstrings' ``extensions``): the
docstrings' reST inline markup read as Markdown code.

The docstrings are numpydoc, written for Sphinx as well: ``:func:`cas_freq.api.load```,
``:math:`\\omega```, double-backtick literals. mkdocstrings renders Markdown, where these
would show their colons and doubled backticks; here each becomes Markdown code.
"""

import re

import griffe

#: A Sphinx role (``:func:`~x.y```, ``:math:`a```) or a reST literal (````x````).
_ROLE = re.compile(r":(?:py:)?\w+:`~?([^`]+)`")
_LITERAL = re.compile(r"``([^`]+)``")


def markdown(text):
    """``text`` with its reST roles and literals as Markdown code."""
    return _LITERAL.sub(r"`\1`", _ROLE.sub(r"`\1`", text))


class ReSTRolesAsCode(griffe.Extension):
    """Rewrite each loaded object's docstring with :func:`markdown`."""

    def on_instance(self, *, obj, **kwargs):
        if obj.docstring is not None:
            obj.docstring.value = markdown(obj.docstring.value)
