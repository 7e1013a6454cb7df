"""``python -m rockscan``: the same as the ``rockscan`` command."""

from rockscan.cli import main

if __name__ == "__main__":
    main(prog_name="rockscan")
