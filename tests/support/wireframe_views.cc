#include "tests/support/wireframe_views.h"

#include <cmath>

#include "shared/util/units.h"

namespace idi::test {

Wireframe Box(const Vec3d& origin, const Vec3d& size, double yaw_rad) {
  Wireframe w;
  const Rigid3d pose = Translation(origin) * RotZ(yaw_rad);
  for (int k = 0; k < 8; ++k) {
    w.vertices.push_back(pose * Vec3d((k & 1) ? size.x() : 0.0, (k & 2) ? size.y() : 0.0, (k & 4) ? size.z() : 0.0));
  }
  for (int k = 0; k < 8; ++k) {
    for (int bit : {1, 2, 4}) {
      if (!(k & bit)) w.edges.emplace_back(k, k | bit);
    }
  }
  return w;
}

void Append(Wireframe* a, const Wireframe& b) {
  const int base = static_cast<int>(a->vertices.size());
  a->vertices.insert(a->vertices.end(), b.vertices.begin(), b.vertices.end());
  for (const auto& [i, j] : b.edges) a->edges.emplace_back(i + base, j + base);
}

Rigid3d LookAt(const Vec3d& centre, const Vec3d& target) {
  const Vec3d z = (target - centre).normalized();
  const Vec3d x = z.cross(Vec3d::UnitZ()).normalized();
  const Vec3d y = z.cross(x);
  Rigid3d world_from_cam;
  world_from_cam.rotation << x, y, z;
  world_from_cam.translation = centre;
  return world_from_cam.Inverse();
}

SyntheticView MakeView(const Wireframe& w, const CameraModel& camera, const Rigid3d& cam_from_world,
                       const SyntheticViewOptions& options, std::mt19937* rng) {
  SyntheticView view;
  view.camera = camera;
  view.cam_from_world = cam_from_world;
  std::normal_distribution<double> noise(0.0, options.point_noise_px);
  std::vector<int> point_of_vertex(w.vertices.size(), -1);
  std::vector<Vec2d> projected(w.vertices.size());
  for (std::size_t v = 0; v < w.vertices.size(); ++v) {
    const auto px = Project(camera, cam_from_world * w.vertices[v]);
    if (!px || !camera.InImage(*px, 2.0)) continue;
    projected[v] = *px;
    point_of_vertex[v] = static_cast<int>(view.features.points.size());
    ViewPoint p;
    p.xy = *px + Vec2d(noise(*rng), noise(*rng));
    p.sigma_px = options.point_noise_px;
    view.features.points.push_back(p);
    view.point_vertex.push_back(static_cast<int>(v));
  }
  for (const auto& [a, b] : w.edges) {
    const int pa = point_of_vertex[static_cast<std::size_t>(a)], pb = point_of_vertex[static_cast<std::size_t>(b)];
    if (pa < 0 || pb < 0) continue;
    const Vec2d xa = projected[static_cast<std::size_t>(a)], xb = projected[static_cast<std::size_t>(b)];
    const double len = (xb - xa).norm();
    if (len < options.min_edge_px) continue;
    const Vec2d d = (xb - xa) / len;
    ViewLine line;
    // The fitted line passes near both noisy points.
    line.line = Line2Through(view.features.points[static_cast<std::size_t>(pa)].xy,
                             view.features.points[static_cast<std::size_t>(pb)].xy);
    line.end1 = xa + options.line_shortening_px * d;
    line.end2 = xb - options.line_shortening_px * d;
    line.extension_px = options.extension_px;
    line.points = {pa, pb};
    const int li = static_cast<int>(view.features.lines.size());
    view.features.lines.push_back(line);
    view.features.points[static_cast<std::size_t>(pa)].lines.push_back(li);
    view.features.points[static_cast<std::size_t>(pb)].lines.push_back(li);
  }
  // Clutter: lines crossing in pairs, making IDI points that are no 3D vertex.
  std::uniform_real_distribution<double> ux(20.0, camera.width - 20.0), uy(20.0, camera.height - 20.0);
  std::uniform_real_distribution<double> ang(0.0, kPi);
  for (int c = 0; c + 1 < options.clutter_lines; c += 2) {
    const Vec2d centre(ux(*rng), uy(*rng));
    const double a1 = ang(*rng), a2 = a1 + 0.5 + ang(*rng) * 0.6;
    ViewPoint p;
    p.xy = centre;
    p.sigma_px = options.point_noise_px;
    const int pi = static_cast<int>(view.features.points.size());
    for (const double a : {a1, a2}) {
      const Vec2d d(std::cos(a), std::sin(a));
      ViewLine line;
      line.line = Line2Through(centre, centre + d);
      line.end1 = centre + 4.0 * d;
      line.end2 = centre + 60.0 * d;
      line.extension_px = options.extension_px;
      line.points = {pi};
      p.lines.push_back(static_cast<int>(view.features.lines.size()));
      view.features.lines.push_back(line);
    }
    view.features.points.push_back(p);
    view.point_vertex.push_back(-1);
  }
  return view;
}

}  // namespace idi::test
