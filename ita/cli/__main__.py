"""`python -m ita.cli ...` does what the `ita` command does (the System Monitor starts runs so)."""

from ita.cli import main

main()
