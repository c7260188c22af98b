"""vision package (see ARCHITECTURE §1, ``docs/vision.md``).

Cameras (:mod:`vision.camera`), target models (:mod:`vision.target`), the Open3D ray-cast renderer
(:mod:`vision.render`) and sensor (:mod:`vision.sensor`), features and matching
(:mod:`vision.features`), and the two observation modes that both return a
:class:`vision.observation.Observation`: rendered (:mod:`vision.rendered`) and geometric
(:mod:`vision.geometric`). Submodules are imported on use (Open3D is slow to import).
"""
