"""Geometry of a mesh that `wcs.fem`, `wcs.scene` and `wcs.contact` all use, below the three of
them: the P1 tetrahedron (`tet`), boundary facets' normals and lengths (`facets`), and the mortar
integrals over two sides of a mesh (`mortar` in 2D, `mortar3d` in 3D), which both the contact
rows and the glued interfaces (`wcs.fem.gluing`) are built from, and the points near points
(`near`: a grid search). It imports only `wcs.errors`."""
