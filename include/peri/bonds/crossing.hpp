// Exact segment crossing for pre-cracks and release stages: the signs of the 2D and 3D orientation
// determinants of doubles, exact for every finite input, the closed-segment test in the xy plane
// (slits) and the closed segment-triangle test in space (polygon cracks) built on them.
// Pure (no MPI, no scene types): tested against a brute-force rational reference and fuzzed alone.
#pragma once

namespace peri {

/// Exact sign of (b - a) x (c - a) from the x and y components of a, b and c: +1 when c lies to
/// the left of the line a -> b, -1 to its right, 0 when the three points are collinear (or
/// coincide). Exact for every finite double (no overflow, underflow or round-off can flip or
/// zero the sign); 0 when any of the six coordinates is NaN or infinite.
int orient2d(const double* a, const double* b, const double* c);

/// True when the closed segments [a, b] and [c, d] (x and y components) have at least one point
/// in common. Degenerate cases follow from that: an end point of one lying on the other counts
/// (touching crosses), collinear segments cross when they overlap or share an end point and not
/// when a gap separates them. A zero-length segment (a == b or c == d in x and y) crosses nothing,
/// nor does a segment with a non-finite coordinate. Symmetric: swapping a and b, c and d, or the
/// two segments gives the same answer bit for bit.
bool segments_cross(const double* a, const double* b, const double* c, const double* d);

/// Exact sign of det [a - d; b - d; c - d] (3-vectors): +1 or -1 by the side of the plane a b c
/// that d lies on, 0 when the four points lie in one plane. Exact for every finite double; 0 when
/// any coordinate is NaN or infinite. Antisymmetric: swapping two arguments flips the sign.
int orient3d(const double* a, const double* b, const double* c, const double* d);

/// True when a, b and c lie on one line (or coincide), exactly.
bool triangle_degenerate(const double* a, const double* b, const double* c);

/// True when the closed segment [p, q] and the closed triangle a b c (3-vectors) have at least one
/// point in common: an end on the triangle or its edges counts, and a segment in the triangle's
/// plane meets it when it touches or overlaps it there. A zero-length segment, a degenerate
/// triangle or a non-finite coordinate meets nothing. Symmetric in p and q, exact.
bool segment_meets_triangle(const double* p, const double* q, const double* a, const double* b, const double* c);

}  // namespace peri
