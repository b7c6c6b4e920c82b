// Concrete prism 10 × 4 × 4 cm (x along its length) with a sawn notch across its width at mid-length:
// 1 cm deep from the bottom face z = 0, 3 mm wide (configs/lattice/notched_prism_tension.yaml).
// Lengths in metres.
SetFactory("OpenCASCADE");
L = 0.10;  B = 0.04;  H = 0.04;   // length (x), width (y), height (z)
a = 0.010; w = 0.003;             // notch depth (z) and width (x)
Box(1) = {0, 0, 0, L, B, H};
Box(2) = {L/2 - w/2, -0.001, -0.001, w, B + 0.002, a + 0.001};
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
