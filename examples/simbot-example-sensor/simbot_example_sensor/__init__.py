"""An example of extending simbot from outside it: a proximity sensor, registered as an entry point."""
