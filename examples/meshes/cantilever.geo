// A 2 m x 0.2 m cantilever cut into 80 x 8 quadrilaterals: the gmsh twin of the built-in grid
// of examples/scenes/cantilever.json. Regenerate the mesh with
//     gmsh -2 -format msh41 cantilever.geo -o cantilever.msh
// (or `pip install gmsh` for the gmsh command).
Point(1) = {0, 0, 0};
Point(2) = {2, 0, 0};
Point(3) = {2, 0.2, 0};
Point(4) = {0, 0.2, 0};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve{1, 3} = 81;
Transfinite Curve{2, 4} = 9;
Transfinite Surface{1};
Recombine Surface{1};
// Named edges for the scene's supports and loads, and the plate itself.
Physical Curve("clamp") = {4};
Physical Curve("tip") = {2};
Physical Surface("plate") = {1};
