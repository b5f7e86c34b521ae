// The vertical cut of the validation report's collapse section (§12): soil 2 m wide and 1 m
// high on a rough base at the level of the toe (its lower right corner), its right face the
// cut. Unstructured first-order triangles of size h; regenerate with
//     sh validation/meshes/make.sh
DefineConstant[ h = 0.1 ];
Point(1) = {0, 0, 0, h};
Point(2) = {2, 0, 0, h};
Point(3) = {2, 1, 0, h};
Point(4) = {0, 1, 0, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Physical Surface("soil") = {1};
Mesh.Algorithm = 6;
