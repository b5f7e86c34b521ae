// The footing layer of the validation report's collapse section (§12): 4 m x 1.6 m, with
// points at the footing's ends (x = 1.8 and 2.2 m on the top) so that its clamp's span
// [1.8, 2.2] falls on mesh edges. Unstructured first-order triangles of size h; regenerate with
//     sh validation/meshes/make.sh
// (which runs gmsh -2 -format msh41 -setnumber h H footing.geo for the three sizes).
DefineConstant[ h = 0.1 ];
Point(1) = {0, 0, 0, h};
Point(2) = {4, 0, 0, h};
Point(3) = {4, 1.6, 0, h};
Point(4) = {2.2, 1.6, 0, h};
Point(5) = {1.8, 1.6, 0, h};
Point(6) = {0, 1.6, 0, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 6};
Line(6) = {6, 1};
Curve Loop(1) = {1, 2, 3, 4, 5, 6};
Plane Surface(1) = {1};
Physical Surface("soil") = {1};
Mesh.Algorithm = 6;
