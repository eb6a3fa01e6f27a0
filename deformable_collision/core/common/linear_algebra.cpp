#include "deformable_collision/core/common/linear_algebra.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace deformable_collision {

template <int N>
SymmetricPseudoInverse<N> pseudoInverseSymmetric(const Eigen::Matrix<double, N, N>& matrix,
                                                 double relative_tolerance) {
  using Matrix = Eigen::Matrix<double, N, N>;
  SymmetricPseudoInverse<N> result;
  result.inverse.setZero();
  result.null_projector.setZero();
  const Eigen::SelfAdjointEigenSolver<Matrix> solver(matrix);
  const auto& eigenvalues = solver.eigenvalues();
  const auto& eigenvectors = solver.eigenvectors();
  const double largest = std::max(0.0, eigenvalues.maxCoeff());
  const double cutoff = largest * relative_tolerance;
  for (int i = 0; i < N; ++i) {
    const auto v = eigenvectors.col(i);
    if (largest > 0.0 && eigenvalues(i) > cutoff) {
      result.inverse += (v * v.transpose()) / eigenvalues(i);
      ++result.rank;
    } else {
      result.null_projector += v * v.transpose();
    }
  }
  return result;
}

template SymmetricPseudoInverse<3> pseudoInverseSymmetric<3>(const Eigen::Matrix3d&, double);
template SymmetricPseudoInverse<9> pseudoInverseSymmetric<9>(const Eigen::Matrix<double, 9, 9>&,
                                                             double);

void extractRotation(const Eigen::Matrix3d& matrix, Eigen::Quaterniond& rotation,
                     int max_iterations) {
  // The iteration is scale-invariant; normalising keeps its tolerances so for tiny and huge
  // objects.
  const double scale = matrix.cwiseAbs().maxCoeff();
  if (!(scale > 0.0) || !std::isfinite(scale)) return;
  const Eigen::Matrix3d normalised = matrix / scale;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    // Maximise tr(R^T A) over R = R0 exp([w]): with B = R0^T A, the gradient is g below and
    // the Hessian is sym(B) - tr(B) I.
    const Eigen::Matrix3d b = rotation.toRotationMatrix().transpose() * normalised;
    const Eigen::Vector3d gradient(b(2, 1) - b(1, 2), b(0, 2) - b(2, 0), b(1, 0) - b(0, 1));
    const Eigen::Matrix3d stretch = 0.5 * (b + b.transpose());
    const double trace = stretch.trace();
    const Eigen::Matrix3d curvature = trace * Eigen::Matrix3d::Identity() - stretch;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
    solver.computeDirect(curvature);
    // Newton's step converges quadratically near the maximum, also for thin or flat
    // stretches where the scaled gradient step of Mueller et al. needs thousands of
    // iterations; away from it (indefinite curvature) the scaled gradient step is safe.
    Eigen::Vector3d step;
    if (solver.info() == Eigen::Success &&
        solver.eigenvalues().minCoeff() > 1e-3 * std::abs(trace)) {
      step = solver.eigenvectors() *
             (solver.eigenvectors().transpose() * gradient).cwiseQuotient(solver.eigenvalues());
    } else {
      step = gradient / (std::abs(trace) + 1e-9);
    }
    double angle = step.norm();
    if (!(angle > 1e-14)) break;
    const Eigen::Vector3d axis = step / angle;
    angle = std::min(angle, 1.0);
    rotation = rotation * Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis));
    rotation.normalize();
  }
}

double spectralNorm(const Eigen::Matrix3d& matrix) {
  // Scaling first keeps the squares in A^T A inside the double range for any finite A.
  if (!matrix.allFinite()) return std::numeric_limits<double>::infinity();
  const double scale = matrix.cwiseAbs().maxCoeff();
  if (scale == 0.0) return 0.0;
  const Eigen::Matrix3d normalised = matrix / scale;
  // The closed form of a 3x3 symmetric eigenproblem: a detection cycle takes up to three
  // norms per cluster, and the iterative solver took 2% of the pile's detection. Its largest
  // eigenvalue is accurate to rounding relative to the matrix; the smaller ones, which lose
  // accuracy, are not used.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(normalised.transpose() * normalised, Eigen::EigenvaluesOnly);
  const double largest_eigenvalue = solver.eigenvalues().maxCoeff();
  // The Frobenius norm bounds the spectral norm from above: a cap on the rounding, and the
  // answer should the closed form ever not give a number (a radius must never shrink to 0).
  const double frobenius = normalised.norm();
  if (!std::isfinite(largest_eigenvalue)) return scale * frobenius;
  return scale * std::min(std::sqrt(std::max(0.0, largest_eigenvalue)), frobenius);
}

}  // namespace deformable_collision
