// Exact segment crossing for pre-cracks and release stages: the sign of the 2D orientation
// determinant of doubles, exact for every finite input, and the closed-segment test built on it.
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

}  // namespace peri
