// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2b maths: beam masses, Dempster's rule, Xiao's measures, discretisation.
#include <gtest/gtest.h>

#include <random>

#include "cleanmap/core/dempster_shafer.h"

using namespace cleanmap;
using ds::Mass;

namespace {

void expectValid(const Mass& m) {
  EXPECT_GE(m.e, -1e-12);
  EXPECT_GE(m.o, -1e-12);
  EXPECT_GE(m.u, -1e-12);
  EXPECT_LE(m.e, 1 + 1e-12);
  EXPECT_NEAR(m.e + m.o + m.u, 1.0, 1e-12);
}

void expectNear(const Mass& a, const Mass& b, double tol = 1e-12) {
  EXPECT_NEAR(a.e, b.e, tol);
  EXPECT_NEAR(a.o, b.o, tol);
  EXPECT_NEAR(a.u, b.u, tol);
}

Mass randomMass(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  double a = u(rng), b = u(rng), c = u(rng);
  const double s = a + b + c;
  return {a / s, b / s, c / s};
}

}  // namespace

TEST(BeamModel, HandComputedValues) {
  DsParams p;  // sigma_m 0.05, sigma_r 0.15 -> sigma^2 = 0.025
  p.lambda_theta = 0.01;
  const ds::BeamModel m(p);
  EXPECT_NEAR(m.sigma, std::sqrt(0.025), 1e-15);
  // r = 0, theta = 0: e' = Phi(0) = 0.5; o' = 1/sqrt(1.025) * Phi(0) = 0.49386...
  const Mass at = m.beam(0.0, 0.0);
  EXPECT_NEAR(at.e, 0.5, 1e-12);
  EXPECT_NEAR(at.o, 0.5 / std::sqrt(1.025), 1e-12);
  // r = -0.3 (beam went 0.3 m past P'): e' = Phi(0.3 / 0.158114) = Phi(1.897367) = 0.971110
  const Mass front = m.beam(-0.3, 0.0);
  EXPECT_NEAR(front.e, 0.9711102, 1e-6);
  // o' = exp(-0.09 / 2.05) / sqrt(1.025) * Phi(-0.3 / (0.158114 * 1.012423)) = Phi(-1.87407) ...
  EXPECT_NEAR(front.o, std::exp(-0.09 / 2.05) / std::sqrt(1.025) * 0.0304593, 1e-6);
  // theta = lambda: f_theta = exp(-1/2) scales e' only.
  const Mass off = m.beam(-0.3, 0.01);
  EXPECT_NEAR(off.e, front.e * std::exp(-0.5), 1e-12);
  EXPECT_NEAR(off.o, front.o, 1e-12);
}

TEST(BeamModel, FrontIsEmptyBehindIsOccupiedFarOffIsUnknown) {
  const ds::BeamModel m(DsParams{});
  const Mass front = m.beam(-1.0, 0.0);  // P well in front of the hit: the beam crossed it
  EXPECT_GT(front.e, 0.99);
  const Mass behind = m.beam(0.5, 0.0);  // P just behind the hit: occupied
  EXPECT_GT(behind.o, behind.e);
  EXPECT_GT(behind.o, behind.u);
  const Mass hidden = m.beam(8.0, 0.0);  // far behind the hit: not seen
  EXPECT_GT(hidden.u, 0.999);
  const Mass off = m.beam(-1.0, 0.05);  // far off the beam (14 lambda): no evidence
  EXPECT_LT(off.e, 1e-30);
}

TEST(BeamModel, MassesAreValidEverywhere) {
  const ds::BeamModel m(DsParams{});
  for (double r = -10; r <= 10; r += 0.01)
    for (double th : {0.0, 0.002, 0.005, 0.01}) expectValid(m.beam(r, th));
}

TEST(Dempster, HandComputedCombination) {
  const Mass a{0.6, 0.1, 0.3}, b{0.2, 0.5, 0.3};
  // K = o1 e2 + e1 o2 = 0.02 + 0.30 = 0.32
  const Mass c = ds::combine(a, b);
  EXPECT_NEAR(c.e, (0.12 + 0.18 + 0.06) / 0.68, 1e-12);
  EXPECT_NEAR(c.o, (0.05 + 0.03 + 0.15) / 0.68, 1e-12);
  EXPECT_NEAR(c.u, 0.09 / 0.68, 1e-12);
}

TEST(Dempster, UnknownIsTheIdentity) {
  const Mass a{0.3, 0.5, 0.2};
  expectNear(ds::combine(a, Mass{}), a);
  expectNear(ds::combine(Mass{}, a), a);
}

TEST(Dempster, CommutativeAndAssociative) {
  std::mt19937 rng(11);
  for (int i = 0; i < 1000; ++i) {
    const Mass a = randomMass(rng), b = randomMass(rng), c = randomMass(rng);
    expectValid(ds::combine(a, b));
    expectNear(ds::combine(a, b), ds::combine(b, a));
    expectNear(ds::combine(ds::combine(a, b), c), ds::combine(a, ds::combine(b, c)), 1e-9);
  }
}

TEST(Dempster, TotalConflictIsUnknownAndReported) {
  bool conflict = false;
  const Mass c = ds::combine(Mass{1, 0, 0}, Mass{0, 1, 0}, &conflict);
  EXPECT_TRUE(conflict);
  expectNear(c, Mass{});
  bool none = false;
  ds::combine(Mass{0.9, 0, 0.1}, Mass{0, 0.9, 0.1}, &none);
  EXPECT_FALSE(none);
}

TEST(Xiao, MeasuresSumToOneAndSeparateConflict) {
  std::mt19937 rng(5);
  for (int i = 0; i < 200; ++i) {
    const Mass a = randomMass(rng), b = randomMass(rng);
    const auto x = ds::xiao(a, b);
    EXPECT_NEAR(x.conf + x.cons + x.unc, 1.0, 1e-12);  // the nine products of a and b
  }
  const auto moved = ds::xiao(Mass{0.9, 0, 0.1}, Mass{0, 0.9, 0.1});  // empty vs occupied
  EXPECT_GT(moved.conf, moved.cons);
  EXPECT_GT(moved.conf, moved.unc);
  const auto same = ds::xiao(Mass{0, 0.9, 0.1}, Mass{0, 0.8, 0.2});
  EXPECT_GT(same.cons, same.conf);
}

TEST(Discretise, BeliefFallsWithRangeAndKeepsTheWinner) {
  const DsParams p;
  EXPECT_NEAR(ds::discreteBelief(0.0, 80.0, p), 0.8, 1e-12);
  EXPECT_NEAR(ds::discreteBelief(80.0, 80.0, p), 0.6, 1e-12);
  EXPECT_NEAR(ds::discreteBelief(40.0, 80.0, p), 0.7, 1e-12);
  expectNear(ds::discretise(Mass{0.5, 0.3, 0.2}, 0.7), Mass{0.7, 0, 0.3});
  expectNear(ds::discretise(Mass{0.2, 0.5, 0.3}, 0.7), Mass{0, 0.7, 0.3});
  expectNear(ds::discretise(Mass{0.2, 0.3, 0.5}, 0.7), Mass{0, 0, 1});
  expectNear(ds::discretise(Mass{0.4, 0.4, 0.2}, 0.7), Mass{0, 0, 1});  // a tie is no evidence
}

TEST(Decision, MajorityOfScansDecides) {
  // Three scans say empty, one says occupied, all with l = 0.7: empty wins -> moving.
  Mass acc;
  for (int i = 0; i < 3; ++i) acc = ds::combine(acc, Mass{0.7, 0, 0.3});
  acc = ds::combine(acc, Mass{0, 0.7, 0.3});
  EXPECT_TRUE(ds::isMoving(acc));
  // Two occupied against one empty: static.
  Mass b;
  b = ds::combine(b, Mass{0.7, 0, 0.3});
  b = ds::combine(b, Mass{0, 0.7, 0.3});
  b = ds::combine(b, Mass{0, 0.7, 0.3});
  EXPECT_FALSE(ds::isMoving(b));
  EXPECT_FALSE(ds::isMoving(Mass{}));  // no evidence: static
}

TEST(BeamModel, TailShortcutEqualsTheClosedForm) {
  // Past 8.5 sigma the Phi factors are skipped; the masses equal the full closed forms.
  const DsParams p;
  const ds::BeamModel m(p);
  for (double r = -5.0; r <= 5.0; r += 0.01) {
    const double theta = 0.002;
    const ds::Mass got = m.beam(r, theta);
    const double f = std::exp(-theta * theta / (2 * p.lambda_theta * p.lambda_theta));
    const double e = f * ds::Phi(-r / m.sigma);
    const double o =
        std::exp(-r * r / (2 * m.s1)) / std::sqrt(m.s1) * ds::Phi(r / (m.sigma * std::sqrt(m.s1)));
    EXPECT_NEAR(got.e, e, 1e-15) << r;
    EXPECT_NEAR(got.o, o, 1e-15) << r;
    EXPECT_NEAR(got.e + got.o + got.u, 1.0, 1e-15);
  }
}

TEST(BeamModel, SinglePrecisionPathAgreesWithTheClosedForm) {
  const DsParams p;
  const ds::BeamModel m(p);
  for (double r = -5.0; r <= 5.0; r += 0.0037)
    for (const double theta : {0.0, 0.003, 0.009}) {
      const ds::Mass a = m.beam(r, theta);
      const ds::Mass b = m.beamFloat(static_cast<float>(r), static_cast<float>(theta * theta));
      EXPECT_NEAR(a.e, b.e, 2e-6) << r;
      EXPECT_NEAR(a.o, b.o, 2e-6) << r;
      EXPECT_NEAR(b.e + b.o + b.u, 1.0, 1e-12);
    }
}
