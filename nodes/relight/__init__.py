"""The relighting: a face's change of light, on the photo's own pixels.

Between the method (the paper's fit: normals, depth, the fit's albedo on the model grid) and the app. A face
is relit as the photo times a smooth change of light, new over old (``lift``): what the photo shows of the
person (pores, stubble, freckles, a beard, brows, make-up, hair over the face) is kept; only where the photo
holds no usable signal is anything painted (``fill``), and then with texture. The hand-offs, each a small
typed value: the photo's shading as the fit explains it (``shading.Shading``), the photo's own shadows told
from dark albedo (``evidence.ShadowEvidence``), the light the photo shows (``lift.photo_light``), the albedo
a fill paints with (``albedo``), and the layer put back into the photo (``compose.FaceLayer``).
``face.FaceRelight`` says which arrays go where for one face, ``nodes`` runs it in the pipeline, ``live``
gives the browser what it needs to relight a face as the user drags the light (``app/view.js``).
"""
