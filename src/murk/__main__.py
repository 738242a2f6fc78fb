"""``python -m murk`` (also what ``torchrun -m murk train ...`` runs)."""

from murk.cli.main import main

if __name__ == "__main__":
    main()
