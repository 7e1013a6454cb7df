"""Data shipped with rockscan: the default library spec and example photos."""
