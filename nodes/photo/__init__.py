"""The input photo: reading it (``loader``), finding its eyes (``eyes``) and mouth line
(``mouth``), and mapping between it and the model grid (``align``)."""
