// Concrete cylinder Ø 5 cm × 10 cm, axis z, lengths in metres (configs/lattice/cylinder_tension.yaml).
SetFactory("OpenCASCADE");
Cylinder(1) = {0, 0, 0, 0, 0, 0.1, 0.025};
