#include "workcell/procedures/ptu_twin.h"

#include <fmt/format.h>

#include <cmath>

#include "shared/sim/render/shapes.h"
#include "workcell/procedures/calibration_procedures.h"

namespace idi::workcell {

// A Biclops camera of the twin: renders what the true camera sees at the true arm and PTU angles.
class PtuTwin::Camera final : public hal::CameraDevice {
 public:
  Camera(PtuTwin* twin, BiclopsSide side) : twin_(twin), side_(side) {}
  std::string name() const override { return std::string("sim-biclops-") + BiclopsSideName(side_); }
  Status Start(const hal::CameraSettings& settings) override {
    if (settings.width != 640 || settings.height != 480 || !settings.gray) {
      return InvalidArgument(name() + ": the twin's cameras deliver 640x480 gray frames");
    }
    started_ = true;
    return Status::Ok();
  }
  Status Stop() override {
    started_ = false;
    return Status::Ok();
  }
  Result<hal::Image> Grab(std::chrono::milliseconds /*timeout*/) override {
    if (!started_) return FailedPrecondition(name() + ": Grab before Start");
    IDI_ASSIGN_OR_RETURN(cv::Mat pixels, twin_->Render(side_, exposure_us_ / kNominalExposureUs));
    hal::Image image;
    image.timestamp_ns = twin_->cell_.clock().NowNs();
    image.sequence = ++sequence_;
    image.camera = name();
    image.pixels = std::move(pixels);
    return image;
  }
  Status SetExposure(double exposure_us) override {
    if (!(exposure_us > 0) || !std::isfinite(exposure_us)) return InvalidArgument(name() + ": exposure must be positive");
    exposure_us_ = exposure_us;
    return Status::Ok();
  }
  // The exposure at which the twin's options.exposure_dn holds.
  static constexpr double kNominalExposureUs = 1000.0;

 private:
  PtuTwin* twin_;
  BiclopsSide side_;
  bool started_ = false;
  uint64_t sequence_ = 0;
  double exposure_us_ = kNominalExposureUs;
};

Status PtuTwinOptions::Check() const {
  IDI_RETURN_IF_ERROR(cell.Check());
  IDI_RETURN_IF_ERROR(truth.Check());
  IDI_RETURN_IF_ERROR(render.Check());
  IDI_RETURN_IF_ERROR(detector.Check());
  if (!(spot_noise_px >= 0) || wall < 0 || wall > 1 || !target_x_z_mm.allFinite() || !(spot_sigma_mm > 0) ||
      !(spot_peak > 0) || !(exposure_dn > 0)) {
    return InvalidArgument(
        "PTU twin: need spot_noise_px >= 0, wall 0 or 1 (left, right), finite target, positive spot and exposure");
  }
  return Status::Ok();
}

std::array<calib::PtuCameraModel, 2> SampleHeadTruth(unsigned seed, const calib::PtuTruthOptions& options) {
  std::mt19937_64 truth_rng(seed * 104729ULL + 3);
  std::array<calib::PtuCameraModel, 2> out;
  out[0] = calib::SamplePtuTruth(BiclopsSide::kLeft, options, truth_rng);
  out[1] = calib::SamplePtuTruth(BiclopsSide::kRight, options, truth_rng);
  return out;
}

PtuTwin::PtuTwin(const PtuTwinOptions& options)
    : options_(options),
      cell_([&] {
        sim::WorkcellTwinOptions c = options.cell;
        c.seed = options.seed;
        return c;
      }()),
      noise_rng_(options.seed * 7919ULL + 17) {
  const Status ok = options_.Check();
  IDI_CHECK(ok.ok(), ok.ToString());
  truth_ = SampleHeadTruth(options.seed, options_.truth);
  for (std::size_t i = 0; i < 2; ++i) {
    const BiclopsSide side = i == 0 ? BiclopsSide::kLeft : BiclopsSide::kRight;
    SimPtuOptions po;
    po.name = std::string("sim-ptu-") + BiclopsSideName(side);
    ptu_[i] = std::make_unique<SimPanTilt>(po, &cell_.clock());
    cameras_[i] = std::make_unique<Camera>(this, side);
  }
}

PtuTwin::~PtuTwin() = default;

const calib::PtuCameraModel& PtuTwin::true_camera(BiclopsSide side) const {
  return truth_[side == BiclopsSide::kLeft ? 0 : 1];
}

Status PtuTwin::AimLaser() {
  // The operator's knowledge: the nominal arms and rail, the approximate walls.
  const sim::WorkcellSetup setup = cell_.Setup();
  CellSetup cs;
  for (const sim::Wall& w : setup.walls) {
    cs.wall_names.push_back(w.name);
    cs.world_from_wall.push_back(w.world_from_wall);
  }
  cs.psi = setup.psi;
  const calib::ArmModel nominal;
  const Rigid3d& wall = cs.world_from_wall.at(static_cast<std::size_t>(options_.wall));
  // The target: on the wall, at robot 1's x and height z (a horizontal line across the wall).
  const Vec3d p0(options_.target_x_z_mm.x(), 0, options_.target_x_z_mm.y());
  const Vec3d n = wall.rotation.col(2);
  const double s = n.dot(wall.translation - p0) / n.y();
  const Vec3d target_world = p0 + s * Vec3d::UnitY();
  IDI_ASSIGN_OR_RETURN(const hal::RailState rail1, cell_.rail(0).Read());
  IDI_ASSIGN_OR_RETURN(const hal::RailState rail2, cell_.rail(1).Read());
  approx_point_ = NominalWorldFromBase(0, nominal, cs, rail1.position_mm).Inverse() * target_world;
  const Vec3d target_base2 = NominalWorldFromBase(1, nominal, cs, rail2.position_mm).Inverse() * target_world;
  return AimLaserArm(cell_.arm(1), cell_.laser(1), nominal.robot, nominal.laser, target_base2);
}

std::optional<Vec3d> PtuTwin::true_point_in_base() const {
  const auto spot = cell_.TrueSpot(1, options_.wall);
  if (!spot) return std::nullopt;
  const sim::Wall& w = cell_.walls().at(static_cast<std::size_t>(options_.wall));
  return cell_.WorldFromBase(0).Inverse() * (w.world_from_wall * Vec3d(spot->x(), spot->y(), 0));
}

TcfPose PtuTwin::TrueTcf() const {
  const Joints q = cell_.true_joints(0);
  return TcfPoseFromTransform(Rx130BaseFromFlange(cell_.true_robot(0).data(), q.data()));
}

std::array<double, 2> PtuTwin::TrueAngles(BiclopsSide side) {
  SimPanTilt& p = *ptu_[side == BiclopsSide::kLeft ? 0 : 1];
  auto st = p.Read();
  IDI_CHECK(st.ok(), st.status().ToString());
  return {st->pan_rad, st->tilt_rad};
}

Result<std::vector<Vec2d>> PtuTwin::ObserveGeometric(BiclopsSide side) {
  const int image = images_++;
  cell_.clock().SleepForNs(40 * hal::kNsPerMs);  // one short-exposure frame
  std::vector<Vec2d> spots;
  const auto point = true_point_in_base();
  if (!point || image == options_.missing_spot_image) return spots;
  const auto angles = TrueAngles(side);
  const auto px = calib::SimulateSpotPixel(true_camera(side), TrueTcf(), angles[0], angles[1], *point,
                                           options_.spot_noise_px, noise_rng_);
  if (px) spots.push_back(*px);
  if (px && image == options_.second_spot_image) spots.push_back(*px + Vec2d(37, -12));
  return spots;
}

Result<cv::Mat> PtuTwin::Render(BiclopsSide side, double exposure_scale) {
  const int image = images_++;
  cell_.clock().SleepForNs(40 * hal::kNsPerMs);
  const calib::PtuCameraModel& truth = true_camera(side);
  const auto angles = TrueAngles(side);
  const Rigid3d base_from_cam = truth.BaseFromCamera(TrueTcf(), angles[0], angles[1]);
  // The scene in robot 1's base frame: the walls and the floor, and the spot where the beam hits.
  const Rigid3d base_from_world = cell_.WorldFromBase(0).Inverse();
  sim::Scene scene;
  for (const sim::Wall& w : cell_.walls()) {
    const Rigid3d base_from_wall = base_from_world * w.world_from_wall;
    scene.solids.push_back(sim::MakeRectangle(w.name, base_from_wall.translation, base_from_wall.rotation.col(0),
                                              base_from_wall.rotation.col(1), w.half_width_mm, w.half_height_mm,
                                              sim::Gray(0.5)));
  }
  const auto point = true_point_in_base();
  if (point && image != options_.missing_spot_image) {
    scene.laser_spots.push_back({*point, options_.spot_sigma_mm, options_.spot_peak});
    if (image == options_.second_spot_image) {
      // A reflection: a fainter copy 150 mm along the wall.
      const Rigid3d base_from_wall = base_from_world * cell_.walls()[static_cast<std::size_t>(options_.wall)].world_from_wall;
      scene.laser_spots.push_back({*point + 150 * base_from_wall.rotation.col(0), options_.spot_sigma_mm,
                                   0.8 * options_.spot_peak});
    }
  }
  sim::RenderOptions r = options_.render;
  r.exposure_dn = options_.exposure_dn * exposure_scale;
  r.seed = static_cast<uint64_t>(options_.seed) * 100003ULL + static_cast<uint64_t>(image);
  return sim::RenderScene(scene, truth.Camera(), base_from_cam.Inverse(), r);
}

PtuDevices PtuTwin::Devices() {
  PtuDevices d;
  d.arm = &cell_.arm(0);
  d.ptu = {ptu_[0].get(), ptu_[1].get()};
  if (options_.mode == PtuSpotMode::kGeometric) {
    d.observe = [this](BiclopsSide side) { return ObserveGeometric(side); };
  } else {
    hal::CameraSettings settings;
    for (auto& c : cameras_) {
      const Status st = c->Start(settings);
      IDI_CHECK(st.ok(), st.ToString());
    }
    d.observe = CameraSpotObserver({cameras_[0].get(), cameras_[1].get()}, options_.detector);
  }
  return d;
}

}  // namespace idi::workcell
