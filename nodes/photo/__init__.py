"""The input photo: reading it (``loader``), finding its faces (``mediapipe``, ``faces``), placing
each on the model grid (``placement``), and mapping between it and the model grid (``align``)."""
