"""Faces to train and test on: ICT-FaceKit identities (``ict``), the procedural anthropometric
generator (``facegen``), and their placement on the model grid (``placement``)."""
