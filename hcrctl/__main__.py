"""``python -m hcrctl`` runs the same entry point as the ``hcrctl`` script.

That is ``entry``, not ``main``: it flushes, runs the atexit handlers and
skips the interpreter's teardown, as the console script does, so the two
cost the same (and exit the same way).
"""

from .cli import entry

if __name__ == "__main__":
    entry()
