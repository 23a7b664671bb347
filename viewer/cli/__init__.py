"""The ``relight`` command: its parser, the commands, what they share (a scene, its look and lights) and
their output paths."""
