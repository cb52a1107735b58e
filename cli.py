"""`python cli.py ...` from a checkout does what the installed `ita` command does."""

from ita.cli import main

if __name__ == "__main__":
    main()
