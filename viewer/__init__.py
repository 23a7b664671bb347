"""Real-time all-frequency relighting of full-body photos of people.

Stages (each a module with one job, plain data between them):
scene bundle (``viewer.scene.bundle``) -> area lights (``viewer.scene.area_lights``) -> GL engine (``viewer.gl``)
-> image / video.  ``viewer.twin`` is the differentiable torch twin of the engine's mathematics.
"""

__version__ = "0.1.0"
