"""Surfaces and light, nothing about faces: normals and the azimuthal equidistant projection
(``normals``), Lambertian shading and reflectance cones (``reflectance``), rasterising
(``raster``), integrating normals to depth (``integrate``)."""
