"""``dms view``: a live web page of one or more daemons, in its own process.

:mod:`dms.viewer.model` keeps what the page shows (no Zenoh, no web), :mod:`dms.viewer.source`
feeds it from the bus through :class:`dms.bus.ZenohClient`, :mod:`dms.viewer.app` serves it
(Starlette, server-sent events) and :mod:`dms.viewer.cli` is the command. The page and the
chart library (uPlot, MIT) are in ``static/``: nothing is fetched at run time.
"""
