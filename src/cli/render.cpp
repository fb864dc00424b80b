// octovk render: a picture of a map's occupied cells, one castRay per pixel on the device, shaded
// on the host by height (colour; a ColorOcTree's cells in their own colours), the face each ray
// entered (light) and distance (haze), with a legend that gives the heights in metres and a scale
// bar.
#include <Eigen/Core>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>

#include "camera.hpp"
#include "command.hpp"
#include "octovk/octovk.hpp"
#include "octovk/vulkan_interop.hpp"
#include "picture.hpp"
#include "png.hpp"
#include "report.hpp"

namespace octovk::cli {

namespace {

constexpr const char* kRenderUsage =
    "octovk render MAP.bt|MAP.ot -o VIEW.png [--eye X Y Z] [--look-at X Y Z] [--size WxH] "
    "[--fov DEG] [--z-max Z] [--max-device-memory BYTES]";
constexpr std::uint32_t kMaxSide = 8192;
constexpr std::uint32_t kDefaultWidth = 800;
constexpr std::uint32_t kDefaultHeight = 600;
constexpr double kDefaultFovDeg = 60.0;
// Rays per castRays call: bounds the host and device memory of large pictures.
constexpr std::size_t kRayBatch = std::size_t{1} << 20;
// Pixels a tile of rows holds without a cap (some 40 MB of rays and samples on the host): large
// enough batches for a GPU, small beside the picture.
constexpr std::size_t kTilePixels = std::size_t{1} << 18;
// Host bytes a pixel holds for the whole run: its colour before the haze (the picture itself)
// and its depth, for the haze, which needs the depth range of all pixels.
constexpr std::size_t kPictureBytesPerPixel = 3 + sizeof(float);

// The legend beside the view: a strip on the right with the height colour bar and a scale bar,
// on pictures large enough to read it; narrower ones are all view.
constexpr std::uint32_t kLegendWidth = 140;
constexpr std::uint32_t kLegendMinWidth = 400, kLegendMinHeight = 200;
const Rgb kLegendBackground{30, 33, 40};
const Rgb kLegendText{230, 232, 236};

Vec3 parseVec3(const ParsedOption& option) {
  const std::vector<double> v = parseNumbers(option, "0 0 1.5");
  return {v[0], v[1], v[2]};
}

std::uint32_t parseSide(const ParsedOption& option, const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const unsigned long long value = std::strtoull(text.c_str(), &end, 10);
  const bool digits = !text.empty() && text.find_first_not_of("0123456789") == std::string::npos;
  if (!digits || end != text.c_str() + text.size() || errno == ERANGE)
    throw UsageError(option.name + " expects WIDTHxHEIGHT in pixels, got '" + option.value +
                     "'; e.g. " + option.name + " 800x600");
  if (value < 1 || value > kMaxSide)
    throw UsageError(option.name + " " + option.value + ": width and height must be 1 to " +
                     std::to_string(kMaxSide) + " pixels; e.g. " + option.name + " 800x600");
  return static_cast<std::uint32_t>(value);
}

// What the ray of one pixel met: the depth along the ray where it entered the hit cell, the
// face it entered (axis 0..2, sign of the outward normal), the cell centre's z. A walk that began
// inside the hit cell (at depth t_start) entered it there.
struct Sample {
  double depth = -1.0;  // < 0: no hit
  int axis = 2;
  double normal_sign = 1.0;
  double z = 0.0;
  double face_u = 0.0, face_v = 0.0;  // entry point on the face, -1..1 across the cell
  Rgb colour{255, 255, 255};          // the hit cell's own colour (colour maps)
};

// Host bytes a ray takes while its tile is cast: its sample, the ray, its result, its pixel and
// start. Device bytes: the query, its result and walk state, and their staging copies.
constexpr std::size_t kHostBytesPerRay =
    sizeof(Sample) + sizeof(Ray) + sizeof(RayHit) + sizeof(std::size_t) + sizeof(double);
std::size_t deviceBytesPerRay() {
  constexpr std::uint32_t kRays = 1024;
  return 2 * (40 + (castRaysResultBytes(kRays) + kRays - 1) / kRays);
}

// The least a picture of `width` x `height` needs under the cap besides the map: the picture,
// and one row of rays with the rows above and below it.
std::size_t leastRenderBytes(std::uint32_t width, std::uint32_t height) {
  return std::size_t{width} * height * kPictureBytesPerPixel +
         std::size_t{width} * (3 * sizeof(Sample) + kHostBytesPerRay + deviceBytesPerRay());
}

// The error of a picture too large for --max-device-memory: what it needs, and the two fixes.
Error pictureOverCap(std::uint32_t width, std::uint32_t height, std::size_t cap,
                     std::size_t map_bytes) {
  const std::size_t need = leastRenderBytes(width, height) + map_bytes;
  const std::size_t picture = std::size_t{width} * height * kPictureBytesPerPixel;
  const std::string message =
      "render --size " + std::to_string(width) + "x" + std::to_string(height) + " needs at least " +
      bytesText(need) + ": " + bytesText(picture) + " for the picture (" +
      std::to_string(kPictureBytesPerPixel) + " bytes a pixel), " +
      bytesText(need - picture - map_bytes) + " for a row of rays and " + bytesText(map_bytes) +
      " for the map, more than " + kMaxDeviceMemoryOption + " = " + bytesText(cap) +
      " allows (on lavapipe it bounds the program's memory). Raise " + kMaxDeviceMemoryOption +
      " to " + std::to_string(need) + " or more, or give a smaller --size";
  return Error(ErrorCode::kOutOfDeviceMemory, message);
}

Sample sampleOf(const RayHit& hit, const Vec3& origin, const Vec3& dir, double resolution,
                double t_start) {
  Sample s;
  const Vec3 centre = hit.end.cast<double>();
  const double half = 0.5 * resolution;
  double t_enter = -std::numeric_limits<double>::max();
  for (int a = 0; a < 3; ++a) {
    if (dir[a] == 0.0) continue;
    const double near_face = centre[a] - (dir[a] > 0 ? half : -half);
    const double t = (near_face - origin[a]) / dir[a];
    if (t > t_enter) {
      t_enter = t;
      s.axis = a;
      s.normal_sign = dir[a] > 0 ? -1.0 : 1.0;
    }
  }
  s.depth = std::max(t_enter, t_start);
  s.z = centre.z();
  const Vec3 entry = origin + s.depth * dir;
  s.face_u = (entry[(s.axis + 1) % 3] - centre[(s.axis + 1) % 3]) / half;
  s.face_v = (entry[(s.axis + 2) % 3] - centre[(s.axis + 2) % 3]) / half;
  return s;
}

Rgb scale(const Rgb& c, double f) {
  const auto one = [f](std::uint8_t v) {
    return static_cast<std::uint8_t>(std::clamp(v * f, 0.0, 255.0) + 0.5);
  };
  return {one(c[0]), one(c[1]), one(c[2])};
}

Rgb mix(const Rgb& a, const Rgb& b, double t) {
  const auto one = [t](std::uint8_t x, std::uint8_t y) {
    return static_cast<std::uint8_t>(std::clamp(x + (y - x) * t, 0.0, 255.0) + 0.5);
  };
  return {one(a[0], b[0]), one(a[1], b[1]), one(a[2], b[2])};
}

// Background for rays that hit nothing: a dark vertical gradient.
Rgb background(std::uint32_t y, std::uint32_t height) {
  const double t = static_cast<double>(y) / std::max<std::uint32_t>(height - 1, 1);
  return mix(Rgb{52, 58, 72}, Rgb{18, 20, 26}, t);
}

std::string numberText(double v) {
  char text[64];
  std::snprintf(text, sizeof(text), "%g", v);
  return text;
}

std::string vec3Text(const Vec3& v) {
  char text[128];
  std::snprintf(text, sizeof(text), "%.3f %.3f %.3f", v.x(), v.y(), v.z());
  return text;
}

}  // namespace

void printRenderHelp(std::ostream& out) {
  out << "octovk render MAP.bt|MAP.ot -o VIEW.png [--eye X Y Z] [--look-at X Y Z] [--size WxH]\n"
         "              [--fov DEG] [--z-max Z]\n"
         "\n"
         "Draws the occupied cells of an OctoMap .bt or .ot map headless on the Vulkan device, "
         "one\n"
         "OctoMap castRay per pixel (unknown space counts as free), coloured by height (a\n"
         "ColorOcTree .ot: each cell in its own colour); from "
      << kLegendMinWidth << "x" << kLegendMinHeight
      << " pixels on, with a height bar\n"
         "and a scale bar on the right. It prints the camera to repeat or adjust.\n"
         "\n"
         "Options:\n"
         "  -o, --output FILE      the picture to write, 8-bit RGB PNG (.png). Required.\n"
         "      --eye X Y Z        camera position in metres (default: above the occupied cells'\n"
         "                         longer side, far enough for all of them to fit)\n"
         "      --look-at X Y Z    point at the picture's centre (default: the occupied cells')\n"
         "      --size WxH         picture size in pixels, each side 1 to "
      << kMaxSide << " (default: " << kDefaultWidth << "x" << kDefaultHeight
      << ")\n"
         "      --fov DEG          vertical field of view in degrees, 1 to 170 (default: "
      << kDefaultFovDeg
      << ")\n"
         "      --z-max Z          hide everything above height Z metres, e.g. a ceiling\n"
         "                         (default: nothing hidden)\n";
  printMaxDeviceMemoryHelp(out, "A map or ray batch");
  out << "  -h, --help             show this help\n"
         "Values: '--name VALUE' or '--name=VALUE' ('--eye=X,Y,Z'). Up in the picture is +z.\n";
}

namespace {

// The occupied cells a picture can show (below --z-max), their box, and the heights that the
// colours span (cell centres: blue at z_low, red at z_low + z_span), or for a colour map
// (ColorOcTree) the cells' own colours instead.
struct Scene {
  std::vector<OccupancyMap::LeafBoxHost> shown;
  Box occupied;
  double z_low = 0.0, z_span = 1.0;
  bool own_colours = false;
};

// How the rays are cast: rows per tile, rays per castRays call.
struct RayBudget {
  std::size_t tile_rows = 1, ray_batch = kRayBatch;
};

class Render final : public Command {
 public:
  bool option(const ParsedOption& opt) override {
    if (opt.name == "--eye") {
      eye_ = parseVec3(opt);
    } else if (opt.name == "--look-at") {
      look_at_ = parseVec3(opt);
    } else if (opt.name == "--size") {
      const std::size_t x = opt.value.find_first_of("xX");
      if (x == std::string::npos)
        throw UsageError(opt.name + " expects WIDTHxHEIGHT in pixels, got '" + opt.value +
                         "'; e.g. " + opt.name + " 800x600");
      width_ = parseSide(opt, opt.value.substr(0, x));
      height_ = parseSide(opt, opt.value.substr(x + 1));
    } else if (opt.name == "--z-max") {
      z_max_ = parseNumber(opt, "2.0 (metres)");
    } else if (opt.name == "--fov") {
      fov_deg_ = parseNumber(opt, "60 (degrees, vertical)");
      if (!(fov_deg_ >= 1.0 && fov_deg_ <= 170.0))
        throw UsageError("--fov " + opt.value +
                         ": the vertical field of view must be 1 to 170 degrees; e.g. --fov 60");
    } else {
      return false;
    }
    return true;
  }

  void check(Invocation& in) override {
    in.checkMapCommand(kRenderUsage);
    if (eye_ && look_at_ && (*eye_ - *look_at_).norm() < 1e-9)
      throw UsageError("--eye and --look-at are the same point; the camera needs a direction");
    // Before the map is read: a picture that cannot fit under the cap beside an empty map.
    const std::size_t cap = in.maxDeviceBytes();
    const std::size_t empty_map = MapParams().minDeviceBytes();
    if (cap > 0 && leastRenderBytes(width_, height_) + empty_map > cap)
      throw pictureOverCap(width_, height_, cap, empty_map);
  }

  int run(Invocation& in) override;

 private:
  // The occupied cells below --z-max and the heights their colours span.
  Scene scene(OccupancyMap& map, const std::string& map_path) const;
  // The camera: --eye and --look-at, or the default framing of the scene in the view.
  Camera camera(const Scene& scene, double resolution, std::uint32_t view_width) const;
  // Tile rows and ray batches that fit --max-device-memory beside the map and the picture.
  RayBudget budget(const Invocation& in, OccupancyMap& map, const Scene& scene) const;

  std::optional<Vec3> eye_;
  std::optional<Vec3> look_at_;
  std::optional<double> z_max_;
  std::uint32_t width_ = kDefaultWidth;
  std::uint32_t height_ = kDefaultHeight;
  double fov_deg_ = kDefaultFovDeg;
};

bool hasLegend(std::uint32_t width, std::uint32_t height) {
  return width >= kLegendMinWidth && height >= kLegendMinHeight;
}

// Casts one ray per pixel of the view in tiles of rows and shades each row once the rows around
// it are cast (its outlines look at them); the haze, last, needs the depth range of the whole
// view. Only the colours before the haze and the depths are kept for the whole view.
class Tracer {
 public:
  Tracer(OccupancyMap& map, const Scene& scene, const Camera& camera, RayBudget budget)
      : map_(map),
        scene_(scene),
        camera_(camera),
        budget_(budget),
        resolution_(map.params().resolution),
        width_(camera.width),
        height_(camera.height),
        image_(camera.width, camera.height),
        depths_(std::size_t{camera.width} * camera.height, -1.0f),
        // A key light over the camera's left shoulder; faces turned away still get the ambient
        // part.
        light_((-camera.forward * 0.55 - camera.right * 0.4 + Vec3::UnitZ()).normalized()),
        pixel_angle_(2.0 * camera.tan_half_v / camera.height) {}

  // Casts and shades every row; the times go to `steps` ("castRays", "shading").
  void run(Steps& steps) {
    while (shaded_rows_ < height_) {
      const auto tile_end = static_cast<std::uint32_t>(
          std::min<std::size_t>(height_, cast_rows_ + budget_.tile_rows));
      steps.run("castRays", [&] { castRows(tile_end); });
      steps.run("shading", [&] { shadeCastRows(); });
    }
    steps.run("shading", [&] { addHaze(); });
  }

  const RgbImage& image() const { return image_; }
  std::size_t cast() const { return cast_; }
  std::size_t hits() const { return hits_; }
  std::size_t whiteHits() const { return white_hits_; }
  double depthMin() const { return depth_min_; }
  double depthMax() const { return depth_max_; }

 private:
  const Sample& sample(std::uint32_t x, std::uint32_t y) const {
    return window_[std::size_t{y - window_row_} * width_ + x];
  }

  // Nothing outside the occupied cells' box stops a ray that ignores unknown space, so each ray
  // starts where it enters the box and ends where it leaves it: the same first occupied cell as
  // from the eye, without walking the empty space in front (and --z-max is exact this way).
  void castRows(std::uint32_t tile_end) {
    window_.resize(std::size_t{tile_end - window_row_} * width_);
    for (std::size_t p = std::size_t{cast_rows_} * width_; p < std::size_t{tile_end} * width_;
         ++p) {
      const Vec3 dir = camera_.direction(static_cast<double>(p % width_) + 0.5,
                                         static_cast<double>(p / width_) + 0.5);
      double t_in, t_out;
      if (!scene_.occupied.clip(camera_.eye, dir, t_in, t_out)) continue;
      // A hair inside the box, so that a start on a cell face lies in the cell behind it.
      if (t_in > 0.0) t_in += 1e-3 * resolution_;
      Ray ray;
      ray.origin = (camera_.eye + t_in * dir).cast<float>();
      ray.direction = dir.cast<float>();
      ray.max_range_m = t_out - t_in + 2.0 * resolution_;
      ray.ignore_unknown = true;
      rays_.push_back(ray);
      ray_pixel_.push_back(p);
      ray_start_.push_back(t_in);
    }
    if (!rays_.empty()) flush();
    cast_rows_ = tile_end;
  }

  void flush() {
    std::vector<RayHit> results;
    for (;;) {
      try {
        results.clear();
        for (std::size_t at = 0; at < rays_.size(); at += budget_.ray_batch) {
          const std::size_t n = std::min(budget_.ray_batch, rays_.size() - at);
          const std::vector<RayHit> part = map_.castRays(std::span(rays_).subspan(at, n));
          results.insert(results.end(), part.begin(), part.end());
        }
        break;
      } catch (const Error& e) {
        // The estimate of a ray's device bytes was short: smaller batches, down to one ray.
        if (e.code() != ErrorCode::kOutOfDeviceMemory || budget_.ray_batch == 1)
          throw withOptionNames(e);
        budget_.ray_batch /= 2;
      }
    }
    for (std::size_t i = 0; i < results.size(); ++i) {
      if (!results[i].hit) continue;
      const std::size_t p = ray_pixel_[i];
      const Vec3 dir = camera_.direction(static_cast<double>(p % width_) + 0.5,
                                         static_cast<double>(p / width_) + 0.5);
      Sample& s = window_[p - std::size_t{window_row_} * width_];
      s = sampleOf(results[i], camera_.eye, dir, resolution_, ray_start_[i]);
      if (scene_.own_colours) {
        // castRays gives a colour map's hit cell's colour, packed (the leaf search() finds).
        const octovk::Rgb c = unpackRgb(results[i].payload);
        s.colour = {c.r, c.g, c.b};
        if (s.colour == Rgb{255, 255, 255}) ++white_hits_;
      }
      depth_min_ = std::min(depth_min_, s.depth);
      depth_max_ = std::max(depth_max_, s.depth);
      ++hits_;
    }
    cast_ += rays_.size();
    rays_.clear();
    ray_pixel_.clear();
    ray_start_.clear();
  }

  // Shades the rows whose neighbours are cast, and drops the samples no row needs any more.
  void shadeCastRows() {
    const std::uint32_t shade_end = cast_rows_ == height_ ? height_ : cast_rows_ - 1;
    for (; shaded_rows_ < shade_end; ++shaded_rows_) shadeRow(shaded_rows_);
    // The row above the next one to shade stays for its outlines.
    const std::uint32_t keep_from = shaded_rows_ > 0 ? shaded_rows_ - 1 : 0;
    window_.erase(window_.begin(),
                  window_.begin() +
                      static_cast<std::ptrdiff_t>(std::size_t{keep_from - window_row_} * width_));
    window_row_ = keep_from;
  }

  void shadeRow(std::uint32_t y) {
    for (std::uint32_t x = 0; x < width_; ++x) {
      const Sample& s = sample(x, y);
      if (s.depth < 0) {
        image_.set(x, y, background(y, height_));
        continue;
      }
      Vec3 normal = Vec3::Zero();
      normal[s.axis] = s.normal_sign;
      double light_f = 0.38 + 0.62 * std::max(0.0, normal.dot(light_));
      // Cell edges where a cell spans several pixels, so that single voxels can be told apart.
      const double cell_px = resolution_ / std::max(s.depth * pixel_angle_, 1e-12);
      if (cell_px > 5.0) {
        const double edge = 1.0 - 2.4 / cell_px;
        if (std::max(std::abs(s.face_u), std::abs(s.face_v)) > edge) light_f *= 0.72;
      }
      // Outlines where the neighbouring pixel lies much farther away (or is background).
      const auto farther = [&](std::uint32_t nx, std::uint32_t ny) {
        const Sample& n = sample(nx, ny);
        return n.depth < 0 || n.depth > s.depth * 1.04 + 3.0 * resolution_;
      };
      if ((x > 0 && farther(x - 1, y)) || (x + 1 < width_ && farther(x + 1, y)) ||
          (y > 0 && farther(x, y - 1)) || (y + 1 < height_ && farther(x, y + 1)))
        light_f *= 0.55;
      const Rgb base =
          scene_.own_colours ? s.colour : heightColor((s.z - scene_.z_low) / scene_.z_span);
      image_.set(x, y, scale(base, light_f));
      depths_[std::size_t{y} * width_ + x] = static_cast<float>(s.depth);
    }
  }

  // The haze, now that the depth range is known.
  void addHaze() {
    const Rgb haze{70, 76, 92};
    for (std::size_t p = 0; p < depths_.size(); ++p) {
      if (depths_[p] < 0) continue;
      const std::size_t at = p * 3;
      const Rgb lit{image_.pixels[at], image_.pixels[at + 1], image_.pixels[at + 2]};
      const double far =
          depth_max_ > depth_min_ ? (depths_[p] - depth_min_) / (depth_max_ - depth_min_) : 0;
      image_.set(static_cast<std::uint32_t>(p % width_), static_cast<std::uint32_t>(p / width_),
                 mix(lit, haze, 0.4 * std::clamp(far, 0.0, 1.0)));
    }
    depths_ = {};
  }

  OccupancyMap& map_;
  const Scene& scene_;
  const Camera& camera_;
  RayBudget budget_;
  double resolution_;
  std::uint32_t width_, height_;
  RgbImage image_;
  std::vector<float> depths_;
  Vec3 light_;
  double pixel_angle_;
  std::vector<Sample> window_;  // the samples of rows [window_row_, cast_rows_)
  std::uint32_t window_row_ = 0, cast_rows_ = 0, shaded_rows_ = 0;
  std::vector<Ray> rays_;
  std::vector<std::size_t> ray_pixel_;
  std::vector<double> ray_start_;
  std::size_t cast_ = 0, hits_ = 0, white_hits_ = 0;
  double depth_min_ = std::numeric_limits<double>::max(), depth_max_ = 0.0;
};

// The scale bar: a round length and its pixels at the look-at point's depth, where the
// picture's scale is what the bar says (nearer things are larger, farther ones smaller).
struct ScaleBar {
  double metres = 1.0, pixels = 0.0, depth_m = 0.0;
};

ScaleBar scaleBar(const Camera& camera, double most_pixels) {
  ScaleBar bar;
  bar.depth_m = (camera.look_at - camera.eye).dot(camera.forward);
  const double metres_per_pixel = 2.0 * bar.depth_m * camera.tan_half_v / camera.height;
  bar.metres = roundLength(most_pixels * metres_per_pixel);
  bar.pixels = bar.metres / metres_per_pixel;
  return bar;
}

void drawScaleBar(Canvas& canvas, double left, double h, const ScaleBar& bar);

// The legend strip at x0 of `canvas`: the height colour bar with its heights in metres (a colour
// map's words on its own colours instead), then the scale bar.
void drawLegend(Canvas& canvas, std::uint32_t x0, const Scene& scene, const ScaleBar& bar) {
  const double h = canvas.height();
  canvas.fill(x0, 0, kLegendWidth, h, kLegendBackground);
  const double left = x0 + 12.0;
  if (scene.own_colours) {
    // No height bar: each cell shows the colour the map holds for it.
    canvas.text("colours: the", left, 16, 13, kLegendText);
    canvas.text("map's own", left, 34, 13, kLegendText);
    canvas.text("(ColorOcTree)", left, 52, 13, kLegendText);
    drawScaleBar(canvas, left, h, bar);
    return;
  }
  canvas.text("height", left, 16, 13, kLegendText);
  // The colour bar, highest at the top; its ticks at round heights.
  const double top = 34, bottom = h - 96, bar_w = 16;
  for (double y = top; y < bottom; ++y)
    canvas.fill(left, y, bar_w, 1, heightColor((bottom - y - 0.5) / (bottom - top)));
  double step = 1.0;
  const std::vector<double> ticks =
      niceTicks(scene.z_low, scene.z_low + scene.z_span,
                std::clamp(static_cast<int>((bottom - top) / 26.0), 2, 10), &step);
  for (const double z : ticks) {
    const double y = bottom - (z - scene.z_low) / scene.z_span * (bottom - top);
    canvas.line(left + bar_w, y, left + bar_w + 5, y, kLegendText);
    canvas.text(tickText(z, step, "m"), left + bar_w + 9, y, 11, kLegendText);
  }
  drawScaleBar(canvas, left, h, bar);
}

// The scale bar at the legend's foot (`left` its left edge, `h` the canvas height), with what it
// measures.
void drawScaleBar(Canvas& canvas, double left, double h, const ScaleBar& bar) {
  const double y = h - 60;
  canvas.text("scale at the look-at", left, y - 26, 11, kLegendText);
  canvas.text(format("point, %s m away", tickText(bar.depth_m, 0.1).c_str()), left, y - 12, 11,
              kLegendText);
  canvas.fill(left, y, bar.pixels, 6, kLegendText);
  canvas.line(left + 0.5, y - 3, left + 0.5, y + 9, kLegendText);
  canvas.line(left + bar.pixels - 0.5, y - 3, left + bar.pixels - 0.5, y + 9, kLegendText);
  canvas.text(tickText(bar.metres, bar.metres, "m"), left + 0.5 * bar.pixels, y + 20, 12,
              kLegendText, Canvas::Align::kCentre);
}

Scene Render::scene(OccupancyMap& map, const std::string& map_path) const {
  const double resolution = map.params().resolution;
  const float occupied_log_odds = occupancyLogOdds(map.params());
  // The cells that can show: occupied, and below --z-max, which cuts at the cell boundary
  // nearest it.
  const double z_cut =
      z_max_ ? std::round(*z_max_ / resolution) * resolution : std::numeric_limits<double>::max();
  Scene scene;
  scene.own_colours = map.params().payload == Payload::kColor;
  scene.shown = map.downloadLeafBoxes();
  std::erase_if(scene.shown, [&](const OccupancyMap::LeafBoxHost& c) {
    return !(c.log_odds >= occupied_log_odds) || c.center[2] - 0.5 * c.size >= z_cut;
  });
  if (scene.shown.empty())
    throw Error(ErrorCode::kInvalidArgument, "map '" + map_path + "' has no occupied cells" +
                                                 (z_max_ ? " below --z-max" : "") +
                                                 ": there is nothing to render");
  for (const OccupancyMap::LeafBoxHost& c : scene.shown) scene.occupied.add(c);
  scene.occupied.max.z() = std::min(scene.occupied.max.z(), z_cut);
  scene.z_low = scene.occupied.min.z() + 0.5 * resolution;  // cell centres: z of a hit
  scene.z_span = std::max(scene.occupied.max.z() - scene.occupied.min.z() - resolution, resolution);
  return scene;
}

Camera Render::camera(const Scene& scene, double resolution, std::uint32_t view_width) const {
  Vec3 look_at = look_at_.value_or(0.5 * (scene.occupied.min + scene.occupied.max));
  Vec3 eye;
  if (eye_) {
    eye = *eye_;
  } else {
    const Vec3 view = defaultView(scene.occupied);
    frame(scene.shown, view, view_width, height_, fov_deg_, !look_at_, look_at, eye);
  }
  if ((eye - look_at).norm() < 1e-9)
    throw UsageError("--eye " + vec3Text(eye) + " is the point the camera looks at; move it");
  // castRay needs its origin inside the map: a cell with a key.
  if (!coordToKey(resolution, eye.cast<float>())) {
    const double edge = 0.5 * resolution - keyToCoord(resolution, Key{0, 0, 0}).x();
    throw UsageError("--eye " + vec3Text(eye) + " lies outside the map's domain (each coordinate " +
                     "within " + numberText(edge) + " m of the origin at this resolution)");
  }
  return Camera(eye, look_at, view_width, height_, fov_deg_);
}

// The memory the rays may take: under a cap, what the map and the picture leave of it.
RayBudget Render::budget(const Invocation& in, OccupancyMap& map, const Scene& scene) const {
  RayBudget budget;
  budget.tile_rows = std::max<std::size_t>(1, kTilePixels / width_);
  const std::size_t cap = in.maxDeviceBytes();
  if (cap == 0) return budget;
  const std::size_t held = map.deviceBytes() + scene.shown.capacity() * sizeof(scene.shown[0]);
  if (leastRenderBytes(width_, height_) + held > cap)
    throw pictureOverCap(width_, height_, cap, held);
  // Half for a tile's rays on the host (and the two rows around it), half for a batch of them on
  // the device.
  const std::size_t room = (cap - held - std::size_t{width_} * height_ * kPictureBytesPerPixel) / 2;
  budget.tile_rows =
      std::clamp<std::size_t>(room / (std::size_t{width_} * (sizeof(Sample) + kHostBytesPerRay)), 3,
                              budget.tile_rows + 2) -
      2;
  budget.ray_batch = std::clamp<std::size_t>(room / deviceBytesPerRay(), 1, kRayBatch);
  return budget;
}

int Render::run(Invocation& in) {
  Steps steps;
  OccupancyMap map = steps.run("reading and upload", [&] { return loadMap(in); });
  const Scene shown = steps.run("reading and upload", [&] { return scene(map, in.input()); });
  const bool legend = hasLegend(width_, height_);
  const std::uint32_t view_width = legend ? width_ - kLegendWidth : width_;
  const Camera view = camera(shown, map.params().resolution, view_width);
  Tracer tracer(map, shown, view, budget(in, map, shown));
  tracer.run(steps);
  const ScaleBar bar = scaleBar(view, kLegendWidth - 28.0);
  steps.run("legend and PNG", [&] {
    Canvas canvas(width_, height_, kLegendBackground);
    canvas.paste(tracer.image(), 0, 0);
    if (legend) drawLegend(canvas, view_width, shown, bar);
    in.files().write(0, [&](const std::string& temporary) { canvas.writePng(temporary); });
    in.files().commit();
  });

  const std::size_t pixels = std::size_t{view_width} * height_;
  Report report(9);
  report.device(in.context())
      .line("map", in.input())
      .line("image",
            format("%ux%u px", width_, height_) +
                (legend ? format(": the view %ux%u, the legend %u px on the right", view_width,
                                 height_, kLegendWidth)
                        : format(" (no legend below %ux%u px)", kLegendMinWidth, kLegendMinHeight)))
      .line("camera", "--eye " + vec3Text(view.eye) + " --look-at " + vec3Text(view.look_at) +
                          format(" --fov %g (vertical; %.1f horizontal)", fov_deg_,
                                 2.0 * std::atan(view.tan_half_h) * 180.0 / M_PI))
      .line("rays", format("%zu cast (pixels whose ray crosses the occupied cells' box), %zu hit "
                           "(%.1f%% of %zu pixels)",
                           tracer.cast(), tracer.hits(),
                           100.0 * static_cast<double>(tracer.hits()) / static_cast<double>(pixels),
                           pixels));
  if (tracer.hits() > 0)
    report.line("depth", format("%.2f to %.2f m", tracer.depthMin(), tracer.depthMax()));
  if (shown.own_colours)
    report.line("colours", format("the map's own (ColorOcTree); %zu of the hits white (no colour "
                                  "set)",
                                  tracer.whiteHits()));
  else
    report.line("heights", format("%.2f to %.2f m, the cells' centres: blue lowest, red highest",
                                  shown.z_low, shown.z_low + shown.z_span));
  return report
      .line("scale", format("%g m = %.0f px at the look-at point, %.2f m from the eye", bar.metres,
                            bar.pixels, bar.depth_m))
      .finish(steps, in.outputs());
}

}  // namespace

std::unique_ptr<Command> makeRender() { return std::make_unique<Render>(); }

}  // namespace octovk::cli
