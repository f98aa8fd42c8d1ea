// A finite-difference check of a back-end SplinePrior's analytic gradient, shared by the tests of
// the priors. Header-only, not core.
#pragma once

#include <gtest/gtest.h>

#include <cmath>

#include "vwe_vo/backend/backend.h"
#include "vwe_vo/trajectory/bspline.h"

namespace vwe_vo {
namespace test {

/// Moves the free control points of `spline` by up to `move_m`, then checks the prior's analytic
/// gradient against central differences (tolerance relative to the gradient's norm).
inline void expectPriorGradientMatchesCentralDifferences(BSpline* spline, int first_free,
                                                         const SplinePrior& prior, double move_m,
                                                         double rel_tol) {
  for (int i = first_free; i < spline->numControlPoints(); ++i)
    spline->setControlPoint(
        i, spline->controlPoints()[i] + move_m * Vec2(std::cos(2.0 * i), std::sin(7.0 * i)));
  Eigen::VectorXd g;
  ASSERT_GT(prior.evaluate(&g), 0.0);
  ASSERT_EQ(g.size(), 2 * (spline->numControlPoints() - first_free));
  const double h = 1e-6;
  for (int k = 0; k < g.size(); ++k) {
    const int i = first_free + k / 2;
    const Vec2 P = spline->controlPoints()[i];
    Vec2 d = Vec2::Zero();
    d(k % 2) = h;
    spline->setControlPoint(i, P + d);
    const double fp = prior.evaluate(nullptr);
    spline->setControlPoint(i, P - d);
    const double fm = prior.evaluate(nullptr);
    spline->setControlPoint(i, P);
    EXPECT_NEAR(g[k], (fp - fm) / (2 * h), rel_tol * g.norm()) << "param " << k;
  }
}

}  // namespace test
}  // namespace vwe_vo
