"""Headless outputs: frames and passes sheets to files, MP4 video, temporal stability metrics."""
