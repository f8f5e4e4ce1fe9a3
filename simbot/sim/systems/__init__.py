"""The systems: one module each, registered under the `simbot.systems` entry-point group."""
