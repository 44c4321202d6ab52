// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <random>
#include <vector>

#include "core/error.h"
#include "geom_test_util.h"
#include "geometry/kabsch.h"

using namespace g2l::geom;
using Catch::Contains;

namespace {

Points apply(const Eigen::Matrix3d& R, const Eigen::Vector3d& t, const Points& p) {
    return ((p.cast<double>() * R.transpose()).rowwise() + t.transpose()).cast<float>();
}

}  // namespace

TEST_CASE("kabsch recovers random rotations to 1e-9 in double and 1e-5 in float",
          "[geometry]") {
    std::mt19937 rng(11);
    for (int trial = 0; trial < 50; ++trial) {
        const Eigen::Matrix3d R = test::random_rotation(rng);
        const Eigen::Vector3d t(100.0 * trial, -50.0, 800.0);
        const PointsD Pd = test::random_points(8 + trial, 100.0, rng).cast<double>();
        const PointsD Qd = (Pd * R.transpose()).rowwise() + t.transpose();
        const Pose pd = kabsch_pose(Pd, Qd);
        CHECK((pd.R - R).cwiseAbs().maxCoeff() < 1e-9);
        CHECK((pd.t - t).cwiseAbs().maxCoeff() < 1e-9);
        CHECK(pd.R.determinant() == Approx(1.0).epsilon(1e-12));
        CHECK((pd.R * pd.R.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <
              1e-12);
        // Float input: the rounding of Q to float limits the accuracy.
        const Points P = Pd.cast<float>();
        const Pose pf = kabsch_pose(P, apply(R, t, P));
        CHECK((pf.R - R).cwiseAbs().maxCoeff() < 1e-5);
        CHECK((pf.t - t).cwiseAbs().maxCoeff() < 1e-2);
    }
}

TEST_CASE("kabsch is exact to 1e-9 when the correspondence is exact in float", "[geometry]") {
    // Rotations by multiples of 90 degrees about the axes map integer points to integer
    // points exactly, so the solve itself is the only error source.
    std::mt19937 rng(2);
    const Eigen::Matrix3d Rs[3] = {
        (Eigen::Matrix3d() << 0, -1, 0, 1, 0, 0, 0, 0, 1).finished(),
        (Eigen::Matrix3d() << 1, 0, 0, 0, 0, -1, 0, 1, 0).finished(),
        (Eigen::Matrix3d() << 0, 0, 1, 0, 1, 0, -1, 0, 0).finished()};
    for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
            const Eigen::Matrix3d R = Rs[a] * Rs[b];
            const Points P = test::random_points(12, 50.0, rng).array().round().matrix();
            const Eigen::Vector3d t(3, -4, 5);
            const Pose pose = kabsch_pose(P, apply(R, t, P));
            CHECK((pose.R - R).cwiseAbs().maxCoeff() < 1e-9);
            CHECK((pose.t - t).cwiseAbs().maxCoeff() < 1e-9);
        }
    }
}

TEST_CASE("kabsch with noise stays close, and weights ignore outliers", "[geometry]") {
    std::mt19937 rng(5);
    std::normal_distribution<double> noise(0.0, 0.5);
    const Eigen::Matrix3d R = test::random_rotation(rng);
    const Points P = test::random_points(200, 100.0, rng);
    Points Q = apply(R, Eigen::Vector3d(1, 2, 3), P);
    for (int i = 0; i < Q.rows(); ++i) {
        for (int c = 0; c < 3; ++c) Q(i, c) += static_cast<float>(noise(rng));
    }
    const Eigen::Matrix3d Rn = kabsch(P, Q);
    const double angle = Eigen::AngleAxisd(Rn * R.transpose()).angle();
    CHECK(angle < 0.01);  // < 0.6 degrees for 0.5 mm noise on a 100 mm cloud

    // Corrupt 10 points; with weight 0 they must not matter at all.
    Points Qo = apply(R, Eigen::Vector3d(1, 2, 3), P);
    std::vector<double> w(200, 1.0);
    for (int i = 0; i < 10; ++i) {
        Qo.row(i) = Eigen::RowVector3f(1000.f * i, -500.f, 42.f);
        w[i] = 0.0;
    }
    const Pose pw = kabsch_pose(P, Qo, w);
    CHECK((pw.R - R).cwiseAbs().maxCoeff() < 1e-5);
    CHECK((pw.t - Eigen::Vector3d(1, 2, 3)).cwiseAbs().maxCoeff() < 1e-2);
    CHECK((kabsch(P, Qo) - R).cwiseAbs().maxCoeff() > 1e-2);  // unweighted is pulled away
}

TEST_CASE("kabsch returns a proper rotation for reflected and degenerate input", "[geometry]") {
    std::mt19937 rng(8);
    const Points P = test::random_points(20, 10.0, rng);
    Points mirrored = P;
    mirrored.col(0) *= -1.f;  // a reflection: no rotation maps P onto it
    const Eigen::Matrix3d R = kabsch(P, mirrored);
    CHECK(R.determinant() == Approx(1.0).epsilon(1e-12));
    CHECK((R * R.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-12);

    Points line(5, 3);
    for (int i = 0; i < 5; ++i) line.row(i) = Eigen::RowVector3f(i, 2.f * i, -float(i));
    const Eigen::Matrix3d Rl = kabsch(line, line);
    REQUIRE(Rl.allFinite());
    CHECK(Rl.determinant() == Approx(1.0).epsilon(1e-12));
    // It must still map the line onto itself.
    const Eigen::Vector3d dir = Eigen::Vector3d(1, 2, -1).normalized();
    CHECK((Rl * dir - dir).norm() < 1e-9);

    const Points same = Points::Constant(4, 3, 7.f);
    const Eigen::Matrix3d Rs = kabsch(same, same);
    CHECK(Rs.allFinite());
    CHECK(Rs.determinant() == Approx(1.0));
}

TEST_CASE("kabsch_batched matches the single solve and recovers rotations in float",
          "[geometry]") {
    std::mt19937 rng(21);
    const int B = 64, K = 8;
    std::vector<float> P(B * K * 3), Q(B * K * 3), R(B * 9, -99.f);
    std::vector<Eigen::Matrix3d> truth(B);
    for (int b = 0; b < B; ++b) {
        truth[b] = test::random_rotation(rng);
        const Points pb = test::random_points(K, 80.0, rng);
        const Points qb = apply(truth[b], Eigen::Vector3d(0, 0, 0), pb);
        std::copy(pb.data(), pb.data() + K * 3, P.begin() + b * K * 3);
        std::copy(qb.data(), qb.data() + K * 3, Q.begin() + b * K * 3);
    }
    kabsch_batched(P.data(), Q.data(), B, K, R.data());
    for (int b = 0; b < B; ++b) {
        const Eigen::Map<const Eigen::Matrix<float, 3, 3, Eigen::RowMajor>> Rb(R.data() + b * 9);
        CHECK((Rb.cast<double>() - truth[b]).cwiseAbs().maxCoeff() < 1e-5);
        const Eigen::Map<const Points> pb(P.data() + b * K * 3, K, 3);
        const Eigen::Map<const Points> qb(Q.data() + b * K * 3, K, 3);
        CHECK((kabsch(Points(pb), Points(qb)).cast<float>() - Rb).cwiseAbs().maxCoeff() < 1e-6);
    }
    kabsch_batched(P.data(), Q.data(), 0, K, nullptr);  // B = 0 is a no-op

    REQUIRE_THROWS_WITH(kabsch_batched(P.data(), Q.data(), B, 2, R.data()), Contains("K >= 3"));
    P[5 * K * 3 + 3 * 2 + 1] = std::nanf("");
    REQUIRE_THROWS_WITH(kabsch_batched(P.data(), Q.data(), B, K, R.data()),
                        Contains("b=5 k=2"));
    REQUIRE_THROWS_WITH(kabsch_batched(P.data(), nullptr, B, K, R.data()), Contains("null"));
}

TEST_CASE("kabsch rejects mismatched, too small and non-finite input", "[geometry]") {
    const Points a = Points::Random(5, 3), b = Points::Random(4, 3);
    REQUIRE_THROWS_WITH(kabsch(a, b), Contains("P has 5 points but Q has 4"));
    const Points two = a.topRows(2);
    REQUIRE_THROWS_WITH(kabsch_pose(two, two), Contains("at least 3"));
    Points c = a;
    c(3, 0) = std::numeric_limits<float>::infinity();
    REQUIRE_THROWS_WITH(kabsch(a, c), Contains("row 3"));
    REQUIRE_THROWS_WITH(kabsch(a, a, std::vector<double>(4, 1.0)), Contains("4 weights for 5"));
    REQUIRE_THROWS_WITH(kabsch(a, a, std::vector<double>{1, 1, -2, 1, 1}),
                        Contains("weight 2") && Contains("-2"));
    REQUIRE_THROWS_WITH(kabsch(a, a, std::vector<double>(5, 0.0)), Contains("sum to 0"));
}
