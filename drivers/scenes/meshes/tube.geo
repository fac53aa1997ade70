// An open tube, axis along z (drivers/scenes/tube_burst.yaml): radius R, length L, triangles of
// edge about h (Gmsh's frontal-Delaunay on the four quarter-cylinders an extruded circle makes).
// Physical groups: "wall" (the surface), "bottom" and "top" (the end rims, z = 0 and z = L).
// Made by the build (build/, cmake target example_meshes):
//   gmsh -2 -bin -format msh41 tube.geo -o tube.msh
// dimension: 2
DefineConstant[ h = 2.5e-3 ];
R = 0.05;
L = 0.3;
Point(1) = {0, 0, 0, h};
Point(2) = {R, 0, 0, h};
Point(3) = {0, R, 0, h};
Point(4) = {-R, 0, 0, h};
Point(5) = {0, -R, 0, h};
Circle(1) = {2, 1, 3};
Circle(2) = {3, 1, 4};
Circle(3) = {4, 1, 5};
Circle(4) = {5, 1, 2};
out[] = Extrude {0, 0, L} { Curve{1, 2, 3, 4}; };
Physical Surface("wall") = {out[1], out[5], out[9], out[13]};
Physical Curve("bottom") = {1, 2, 3, 4};
Physical Curve("top") = {out[0], out[4], out[8], out[12]};
Mesh.Algorithm = 6;  // frontal-Delaunay
