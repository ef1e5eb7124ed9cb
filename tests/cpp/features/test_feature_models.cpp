// Feature observation models: each against an independent rotation-matrix
// projection written here, analytic Jacobians against central finite
// differences (double), the float build against the double one, the feature paper's
// line-point sign, and the camera-offset coupling.
#include <gtest/gtest.h>

#include <random>

#include "fsw/features/feature_models.hpp"

using namespace fsw;

namespace {

struct Case {
  Eigen::Quaterniond q_lf;
  Eigen::Vector3d r_l;
};

// Poses looking at the lP origin from 20-60 m, random attitude about the line of sight.
std::vector<Case> sample_poses(unsigned seed, int n = 40) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(20.0, 60.0);
  std::vector<Case> out;
  for (int k = 0; k < n; ++k) {
    // Camera boresight (body z) points from the follower at the leader.
    const Eigen::Vector3d dir = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    Case c;
    c.r_l = -dir * u(rng);
    const Eigen::Quaterniond align = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), dir);
    const Eigen::Quaterniond roll(Eigen::AngleAxisd(g(rng), Eigen::Vector3d::UnitZ()));
    const Eigen::Quaterniond tilt(Eigen::AngleAxisd(0.05 * g(rng), Eigen::Vector3d(g(rng), g(rng), 0).normalized()));
    c.q_lf = (align * roll * tilt).normalized();
    out.push_back(c);
  }
  return out;
}

CameraMount<double> mount() {
  CameraMount<double> cam;
  cam.focal_m = 0.5;
  cam.camera_offset_f_m = Eigen::Vector3d(0.4, -0.3, 1.2);
  cam.feature_origin_l_m = Eigen::Vector3d(0.2, 0.1, -1.0);
  return cam;
}

DualQuat<double> pose(const Case& c) { return DualQuat<double>::from_rotation_translation(c.q_lf, c.r_l); }

// Independent: camera-frame point by rotation matrices only.
Eigen::Vector3d camera_point(const Case& c, const CameraMount<double>& cam, const Eigen::Vector3d& D) {
  const Eigen::Matrix3d R = c.q_lf.toRotationMatrix();
  const Eigen::Vector3d cam_pos_l = c.r_l + R * cam.camera_offset_f_m;
  return R.transpose() * (cam.feature_origin_l_m + D - cam_pos_l);
}

Eigen::Vector2d pinhole(const Eigen::Vector3d& d, double f) {
  return f * Eigen::Vector2d(d.x() / d.z(), d.y() / d.z());
}

// Perturbed pose: q (x) Exp(dtheta), r + dr.
DualQuat<double> perturbed(const Case& c, const Eigen::Matrix<double, 6, 1>& e) {
  const Eigen::Quaterniond q = c.q_lf * fsw::exp(Eigen::Vector3d(e.head<3>()));
  return DualQuat<double>::from_rotation_translation(q, c.r_l + e.tail<3>());
}

const Eigen::Vector3d kD[4] = {{1, 1, 0}, {-1, 1, 0}, {-1, -1, 0}, {1, -1, 0}};
const Eigen::Vector3d kLineL[4] = {{-1, 0, 0}, {0, -1, 0}, {1, 0, 0}, {0, 1, 0}};
const Eigen::Vector3d kLineM(0, 0, 1);

}  // namespace

TEST(FeatureModelsTest, PointEqualsRotationMatrixProjection) {
  const auto cam = mount();
  for (const auto& c : sample_poses(1)) {
    for (const auto& D : kD) {
      Eigen::Vector2d z;
      ASSERT_TRUE(point_model(pose(c), cam, D, z, static_cast<Mat26<double>*>(nullptr)));
      EXPECT_LE((z - pinhole(camera_point(c, cam, D), cam.focal_m)).norm(), 1e-14);
    }
  }
}

TEST(FeatureModelsTest, LinePointIsFootOfPerpendicularOfProjectedLine) {
  const auto cam = mount();
  for (const auto& c : sample_poses(2)) {
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector3d l = kLineL[i];
      const Eigen::Vector3d p = l.cross(kLineM);  // point of the line nearest the lP origin (m = p x l)
      ASSERT_LE((p.cross(l) - kLineM).norm(), 1e-15);
      // Independent: project two points of the line, foot of the perpendicular from the image origin.
      const Eigen::Vector2d a = pinhole(camera_point(c, cam, p - 0.5 * l), cam.focal_m);
      const Eigen::Vector2d b = pinhole(camera_point(c, cam, p + 0.5 * l), cam.focal_m);
      const Eigen::Vector2d dir = (b - a).normalized();
      const Eigen::Vector2d foot = a - a.dot(dir) * dir;
      Eigen::Vector2d z;
      ASSERT_TRUE(line_model(pose(c), cam, l, kLineM, z, static_cast<Mat26<double>*>(nullptr)));
      EXPECT_LE((z - foot).norm(), 1e-12 * (1 + foot.norm()));
    }
  }
}

TEST(FeatureModelsTest, SeedEq9SignGivesTheMirrorOfTheFoot) {
  // The paper's eq. 9 (+f m_z m_x / rho, ...) is not on the image line unless the
  // foot is the image origin; eq. 6's plane equation has the same sign slip.
  const auto cam = mount();
  const Case c = sample_poses(3)[0];
  Vec3<double> lc, mc;
  transform_line(camera_from_features(pose(c), cam), kLineL[0], kLineM, lc, mc);
  Eigen::Vector2d z;
  ASSERT_TRUE(line_model(pose(c), cam, kLineL[0], kLineM, z, static_cast<Mat26<double>*>(nullptr)));
  const double rho = mc.x() * mc.x() + mc.y() * mc.y();
  const Eigen::Vector2d seed(cam.focal_m * mc.x() * mc.z() / rho, cam.focal_m * mc.y() * mc.z() / rho);
  EXPECT_LE((seed + z).norm(), 1e-15);
  // The correct point satisfies m . [x, y, f] = 0; the feature paper's does not.
  EXPECT_NEAR(mc.x() * z.x() + mc.y() * z.y() + mc.z() * cam.focal_m, 0.0, 1e-14);
  EXPECT_GT(std::abs(mc.x() * seed.x() + mc.y() * seed.y() + mc.z() * cam.focal_m), 1e-6);
}

TEST(FeatureModelsTest, CirclePointEqualsRodriguesAboutTheTwistThenProjection) {
  const auto cam = mount();
  const Eigen::Vector3d lt(0, std::sqrt(0.5), std::sqrt(0.5)), mt(-3, 1, -1), S0(1, 3, -2);
  const Eigen::Vector3d p_axis = lt.cross(mt);
  for (const auto& c : sample_poses(4)) {
    for (double phi : {0.0, 0.7, 2.0, 4.5}) {
      const Eigen::Vector3d Sphi = p_axis + Eigen::AngleAxisd(phi, lt) * (S0 - p_axis);
      const Eigen::Vector3d d = camera_point(c, cam, Sphi);
      Eigen::Vector2d z;
      const bool ok = circle_model(pose(c), cam, lt, mt, S0, phi, z, static_cast<Mat26<double>*>(nullptr),
                                   static_cast<Vec2<double>*>(nullptr));
      ASSERT_EQ(ok, d.z() > cam.min_depth_m);
      if (ok) {
        EXPECT_LE((z - pinhole(d, cam.focal_m)).norm(), 1e-13);
      }
    }
  }
}

namespace {
template <typename Model>
void check_jacobian(const Case& c, Model model) {
  Eigen::Vector2d z0;
  Mat26<double> H;
  ASSERT_TRUE(model(pose(c), z0, &H));
  Mat26<double> Hfd;
  for (int j = 0; j < 6; ++j) {
    const double h = j < 3 ? 1e-6 : 1e-5;
    Eigen::Matrix<double, 6, 1> e = Eigen::Matrix<double, 6, 1>::Zero();
    e(j) = h;
    Eigen::Vector2d zp, zm;
    ASSERT_TRUE(model(perturbed(c, e), zp, nullptr));
    ASSERT_TRUE(model(perturbed(c, -e), zm, nullptr));
    Hfd.col(j) = (zp - zm) / (2 * h);
  }
  EXPECT_LE((H - Hfd).norm(), 1e-6 * (1 + H.norm())) << "H\n" << H << "\nFD\n" << Hfd;
}
}  // namespace

TEST(FeatureModelsTest, PointJacobianMatchesCentralDifferences) {
  const auto cam = mount();
  for (const auto& c : sample_poses(5, 15))
    for (const auto& D : kD)
      check_jacobian(c, [&](const DualQuat<double>& P, Eigen::Vector2d& z, Mat26<double>* H) {
        return point_model(P, cam, D, z, H);
      });
}

TEST(FeatureModelsTest, LineJacobianMatchesCentralDifferences) {
  const auto cam = mount();
  for (const auto& c : sample_poses(6, 15))
    for (const auto& l : kLineL)
      check_jacobian(c, [&](const DualQuat<double>& P, Eigen::Vector2d& z, Mat26<double>* H) {
        return line_model(P, cam, Vec3<double>(l), Vec3<double>(kLineM), z, H);
      });
}

TEST(FeatureModelsTest, CircleJacobiansMatchCentralDifferences) {
  const auto cam = mount();
  const Eigen::Vector3d lt(1, 0, 0), mt(0, 1, 0), S0(2, 1, -1);
  for (const auto& c : sample_poses(7, 15)) {
    for (double phi : {0.3, 2.5}) {
      check_jacobian(c, [&](const DualQuat<double>& P, Eigen::Vector2d& z, Mat26<double>* H) {
        return circle_model(P, cam, lt, mt, S0, phi, z, H, static_cast<Vec2<double>*>(nullptr));
      });
      Eigen::Vector2d z, zp, zm, hphi;
      Mat26<double> H;
      ASSERT_TRUE(circle_model(pose(c), cam, lt, mt, S0, phi, z, &H, &hphi));
      const double h = 1e-6;
      circle_model(pose(c), cam, lt, mt, S0, phi + h, zp, static_cast<Mat26<double>*>(nullptr),
                   static_cast<Vec2<double>*>(nullptr));
      circle_model(pose(c), cam, lt, mt, S0, phi - h, zm, static_cast<Mat26<double>*>(nullptr),
                   static_cast<Vec2<double>*>(nullptr));
      EXPECT_LE((hphi - (zp - zm) / (2 * h)).norm(), 1e-7 * (1 + hphi.norm()));
    }
  }
}

TEST(FeatureModelsTest, CameraOffsetCouplesRotationIntoTheImage) {
  // A pure rotation of the follower about its centre of mass moves the lens
  // when the camera is off the centre of mass: the attitude columns of H are
  // J [d]x (turning the camera in place) plus the lever-arm term J [p_f]x.
  auto cam = mount();
  const Case c = sample_poses(8)[0];
  const Eigen::Vector3d d = camera_point(c, cam, kD[0]);
  Eigen::Matrix<double, 2, 3> J;
  Eigen::Vector2d z;
  ASSERT_TRUE(project(d, cam.focal_m, cam.min_depth_m, z, &J));
  Mat26<double> H;
  ASSERT_TRUE(point_model(pose(c), cam, kD[0], z, &H));
  const Eigen::Matrix<double, 2, 3> lever = H.leftCols<3>() - J * skew(d);
  EXPECT_LE((lever - J * skew(cam.camera_offset_f_m)).norm(), 1e-14);
  EXPECT_GT(lever.norm(), 1e-3);
  // With the camera at the centre of mass the lever-arm term vanishes.
  auto cam0 = cam;
  cam0.camera_offset_f_m.setZero();
  const Eigen::Vector3d d0 = camera_point(c, cam0, kD[0]);
  ASSERT_TRUE(project(d0, cam0.focal_m, cam0.min_depth_m, z, &J));
  ASSERT_TRUE(point_model(pose(c), cam0, kD[0], z, &H));
  EXPECT_LE((H.leftCols<3>() - J * skew(d0)).norm(), 1e-14);
}

TEST(FeatureModelsTest, BehindTheCameraIsNotImageable) {
  const auto cam = mount();
  Case c = sample_poses(9)[0];
  c.q_lf = c.q_lf * Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));  // boresight away
  Eigen::Vector2d z;
  EXPECT_FALSE(point_model(pose(c), cam, kD[0], z, static_cast<Mat26<double>*>(nullptr)));
}

TEST(FeatureModelsTest, LineThroughLensPlaneParallelToImageIsNotImageable) {
  Vec2<double> z;
  EXPECT_FALSE(line_point(Vec3<double>(0, 0, 1), 0.5, z, static_cast<Eigen::Matrix<double, 2, 3>*>(nullptr)));
}

TEST(FeatureModelsTest, FloatBuildAgreesWithDouble) {
  const auto cam = mount();
  CameraMount<float> camf;
  camf.focal_m = 0.5f;
  camf.camera_offset_f_m = cam.camera_offset_f_m.cast<float>();
  camf.feature_origin_l_m = cam.feature_origin_l_m.cast<float>();
  for (const auto& c : sample_poses(10, 10)) {
    const auto Pf = DualQuat<float>::from_rotation_translation(c.q_lf.cast<float>(), c.r_l.cast<float>());
    Eigen::Vector2d zd;
    Vec2<float> zf;
    Mat26<double> Hd;
    Mat26<float> Hf;
    ASSERT_TRUE(point_model(pose(c), cam, kD[1], zd, &Hd));
    ASSERT_TRUE(point_model(Pf, camf, Vec3<float>(kD[1].cast<float>()), zf, &Hf));
    EXPECT_LE((zf.cast<double>() - zd).norm(), 1e-6 * (1 + zd.norm()) * 60);
    ASSERT_TRUE(line_model(pose(c), cam, kLineL[1], kLineM, zd, &Hd));
    ASSERT_TRUE(line_model(Pf, camf, Vec3<float>(kLineL[1].cast<float>()), Vec3<float>(kLineM.cast<float>()), zf, &Hf));
    EXPECT_LE((zf.cast<double>() - zd).norm(), 1e-5 * (1 + zd.norm()));
  }
}
