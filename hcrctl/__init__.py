"""hcrctl: the command-line console for the HCR mobile robot.

Kept deliberately empty of imports: pyserial imports our URL-handler package on
every open, and a one-shot command pays for every module loaded at start-up.
"""

__version__ = "0.1.0"
