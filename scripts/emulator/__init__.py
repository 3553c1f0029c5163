"""Parts of scripts/emulate.py that run whole jobs on the emulated board (fil.py:
firmware in the loop). Imported by emulate.py; not a program of its own."""
