#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace deformable_collision {

/// Result of a symmetric positive semi-definite pseudo-inversion.
template <int N>
struct SymmetricPseudoInverse {
  Eigen::Matrix<double, N, N> inverse;  ///< Moore-Penrose inverse on the well-conditioned range.
  Eigen::Matrix<double, N, N> null_projector;  ///< Projector onto the discarded (near-null) space.
  int rank = 0;
};

/// Pseudo-inverts a symmetric positive semi-definite matrix. Eigenvalues below
/// `relative_tolerance` times the largest one count as zero, so singular moment matrices
/// (coplanar, collinear or coincident points) invert without blowing up. A zero matrix
/// yields a zero inverse and an identity null projector.
template <int N>
SymmetricPseudoInverse<N> pseudoInverseSymmetric(const Eigen::Matrix<double, N, N>& matrix,
                                                 double relative_tolerance = 1e-10);

/// Rotation part of the polar decomposition of `matrix`: the rotation R maximising
/// tr(R^T matrix), found by Newton steps on the rotation group (falling back to the scaled
/// gradient step of Mueller et al. 2016 where the problem is not locally convex),
/// warm-started from `rotation`, which is updated in place. Converges to machine precision
/// in a few steps also for thin and flat stretches. It never produces NaN: a zero,
/// rank-deficient or inverted matrix leaves a proper rotation reachable from the warm
/// start, which keeps degenerate clusters temporally coherent where an SVD would pick
/// arbitrary axes.
void extractRotation(const Eigen::Matrix3d& matrix, Eigen::Quaterniond& rotation,
                     int max_iterations = 30);

/// Largest singular value of a 3x3 matrix (spectral norm), robust for zero, degenerate and
/// inverted matrices and finite for any finite input; never below the true value by more
/// than rounding (callers that need an upper bound add a relative margin).
double spectralNorm(const Eigen::Matrix3d& matrix);

}  // namespace deformable_collision
