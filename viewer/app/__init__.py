"""The interactive viewer (``relight view``): window, input, panel, recording. Needs a display."""

from viewer.app.viewer_app import ViewerApp, ViewerConfig, run_viewer

__all__ = ["ViewerApp", "ViewerConfig", "run_viewer"]
