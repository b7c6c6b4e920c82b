// The acrylic plate of the impact verification (slab_impact.yaml): 1 × 1 × 0.08 m, linear tetrahedra
// of about 5 cm, 4 cm near the top face's centre. Groups: `volume`, `top` (the
// face the sphere hits: the coupling interface), `sides` (the four faces, clamped).
// Regenerate: gmsh -3 -format msh41 slab.geo -o slab.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 0.08};
Point(100) = {0.5, 0.5, 0.08};
Field[1] = Distance;
Field[1].PointsList = {100};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = 0.04;
Field[2].SizeMax = 0.05;
Field[2].DistMin = 0.05;
Field[2].DistMax = 0.25;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
Physical Volume("volume") = {1};
Physical Surface("top") = Surface In BoundingBox{-0.01, -0.01, 0.079, 1.01, 1.01, 0.081};
Physical Surface("sides") = {1, 2, 3, 4};
