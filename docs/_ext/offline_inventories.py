"""Sphinx extension: a build without a network still passes with warnings as errors.

intersphinx fetches the numpy, SciPy, Matplotlib and python-control inventories at each
build. Without a network (CI reaches only package registries) none can be fetched, and
intersphinx says so in one warning with no warning type, which ``suppress_warnings``
therefore cannot name. This extension demotes that message to an info line, and only when
the network could not be reached (a connection error or a timeout): an inventory that
answers wrongly (a mistyped address, HTTP 404), or any other warning, still fails the build.
Offline, those names are plain text instead of links.
"""

from __future__ import annotations

import logging

#: the logger intersphinx warns through (sphinx.util.logging prefixes "sphinx.")
INTERSPHINX_LOGGER = "sphinx.sphinx.ext.intersphinx"
UNREACHABLE = "failed to reach any of the inventories"
#: what requests says when there is no network: DNS failure, refused connection, no answer
OFFLINE_CAUSES = ("ConnectionError", "Timeout")


class OfflineInventories(logging.Filter):
    """Demote "failed to reach any of the inventories" to info when the cause is no network."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno == logging.WARNING and str(record.msg).startswith(UNREACHABLE):
            text = record.getMessage()
            if any(cause in text for cause in OFFLINE_CAUSES):
                record.levelno, record.levelname = logging.INFO, "INFO"
                record.msg = "intersphinx: no inventory reachable (offline?), names stay plain text: " + str(record.msg)
        return True


def setup(app):  # noqa: ANN001, ANN201
    logger = logging.getLogger(INTERSPHINX_LOGGER)
    if not any(isinstance(f, OfflineInventories) for f in logger.filters):
        logger.addFilter(OfflineInventories())
    return {"parallel_read_safe": True, "parallel_write_safe": True}
