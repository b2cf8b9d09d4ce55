"""``python -m hcrctl`` runs the same entry point as the ``hcrctl`` script."""

from .cli import main

if __name__ == "__main__":
    main()
