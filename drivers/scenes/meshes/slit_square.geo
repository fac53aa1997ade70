// The 50 mm square membrane of example 7.1 (drivers/scenes/slit_membrane_mesh.yaml) as an
// unstructured triangle mesh: Gmsh's frontal-Delaunay triangles of edge h. h = 0.168 mm gives
// the grid scene's node density (one node per 0.15625^2 mm^2; an equilateral mesh of edge h has
// one per (sqrt(3)/2) h^2). Made by the build (build/, cmake target example_meshes):
//   gmsh -2 -bin -format msh41 slit_square.geo -o slit_square.msh
// Another edge length: gmsh ... -setnumber h 0.3e-3.
DefineConstant[ h = 0.168e-3 ];
L = 0.025;
Point(1) = {-L, -L, 0, h};
Point(2) = { L, -L, 0, h};
Point(3) = { L,  L, 0, h};
Point(4) = {-L,  L, 0, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Physical Surface("sheet") = {1};
Mesh.Algorithm = 6;  // frontal-Delaunay
