// The 10 m bar of the split-bar verification as one mesh with its two halves as groups (for the
// monolithic reference of the mass-ratio study, whose halves differ in cross-section).
// Regenerate: gmsh -1 -format msh41 split_bar.geo -o split_bar.msh
Point(1) = {0, 0, 0};
Point(2) = {5, 0, 0};
Point(3) = {10, 0, 0};
Line(1) = {1, 2};
Line(2) = {2, 3};
Transfinite Curve{1, 2} = 51;
Physical Point("start") = {1};
Physical Point("interface") = {2};
Physical Point("end") = {3};
Physical Curve("left") = {1};
Physical Curve("right") = {2};
