// The unit square of the validation report's collapse section (§12): the block squeezed between
// smooth platens and the vertical cut. Unstructured first-order triangles of size h; regenerate
// with
//     sh validation/meshes/make.sh
DefineConstant[ h = 0.1 ];
Point(1) = {0, 0, 0, h};
Point(2) = {1, 0, 0, h};
Point(3) = {1, 1, 0, h};
Point(4) = {0, 1, 0, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Physical Surface("soil") = {1};
Mesh.Algorithm = 6;
