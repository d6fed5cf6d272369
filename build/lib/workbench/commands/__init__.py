"""Sub-commands of `workbench`. Each module defines `register(subparsers)`; cli.py lists them."""
