"""The simulated camera's renderer: ray casting into a PyBullet client's visual shapes.

meshes (visual shapes as triangles, OBJ/MTL), scene (static and moving ray-casting scenes), rays (camera rays,
hit geometry), view (one camera frame after frame, the static part cached), surfaces (finishes, colours,
textures), lighting (lamp, fills, exposure, colour noise), renderer (`RayRenderer`), stereo (`ActiveStereo`),
tiny (PyBullet's TinyRenderer for the calibration scenes). docs/simulation.md describes them.
"""
