"""The pure stages: arrays in, dataclasses out.

Nothing here reads or writes files, draws, runs folders or parses a command
line; every module imports only ``rockscan.core`` (and the standard scientific
stack). See the README's Development section for the layers.
"""
