"""``dms face``: the robot's face and tablet as one web page, for a person in front of it.

A running daemon's robot gets eyes that blink and look where it looks, a mouth that moves
while it speaks, cheeks in its LED colour, a voice (the browser's speech synthesis) and a
tablet for menus and answers; the person's taps, typed answers, touches, arrival and
departure go back to the daemon as perception.

:mod:`dms.face.feed` keeps what the page shows (no Zenoh, no web), :mod:`dms.face.link`
feeds it from the bus and publishes what the person does, :mod:`dms.face.voice`
transcribes push-to-talk offline (pocketsphinx, the ``dms[voice]`` extra),
:mod:`dms.face.app` serves the page behind :mod:`dms.face.access`, and
:mod:`dms.face.cli` is the command. The page, its script and the icons (Lucide, ISC) are
in ``static/``: nothing is fetched at run time.
"""
