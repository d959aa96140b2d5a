"""``dms studio``: a web page where a person who does not program builds, tries and saves
a behavior with the mouse, as ROS Commander lets its users do.

:mod:`dms.studio.palette` lists the blocks from their models, :mod:`dms.studio.check`
validates a document with the real loader, :mod:`dms.studio.folder` opens and saves the
behavior files (comments and key order kept), :mod:`dms.studio.trial` runs a behavior or
one state on the simulated Mini, :mod:`dms.studio.rules` checks the DMSL rules pane as
``dms rules check`` does, :mod:`dms.studio.link` reaches a running daemon (its robot's
joints, its frames, a try on its robot) and :mod:`dms.studio.daemon_try` is the daemon's
side of that try. :mod:`dms.studio.app` serves it all behind the viewer's host guard and
the token both pages ask for (:mod:`dms.viewer.auth`), and :mod:`dms.studio.cli` is the
command. The page and its layout library (dagre, MIT) are in ``static/``.
"""
