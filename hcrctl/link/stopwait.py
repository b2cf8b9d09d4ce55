"""How long a rescue keeps re-opening a lost port to deliver stop, by default (``--stop-wait``).

A module of its own so the CLI's option table, the connection context and
the client can all say it without importing the client (some 4 ms of every
start-up, ``monitor --from`` and ``hex decode`` included).
"""

DEFAULT_WAIT_S = 30.0
