"""The statistical model of facial surface normals (``shape_model``), the faces it is trained
on (``faces``: ICT-FaceKit identities, the procedural generator; ``sources`` names them) and
the built-in models (``default_model``)."""
