// octovk render: a picture of a map's occupied cells, one castRay per pixel on the device, shaded
// on the host by height (colour), the face each ray entered (light) and distance (haze).
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
#include "png.hpp"

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

void printRenderHelp(std::ostream& out) {
  out << "octovk render MAP.bt|MAP.ot -o VIEW.png [--eye X Y Z] [--look-at X Y Z] [--size WxH]\n"
         "              [--fov DEG] [--z-max Z]\n"
         "\n"
         "Renders the occupied cells of an OctoMap .bt or .ot map headless on the Vulkan device:\n"
         "one ray per pixel from the eye, cast by OctoMap's castRay rules on the device with\n"
         "unknown space treated as free, stopping at the first occupied cell (each ray starts\n"
         "where it enters the occupied cells' bounding box: nothing before it can stop it).\n"
         "The picture is coloured by the height of the cell hit (blue low, red high, over the\n"
         "z range of the occupied cells shown), lit by the face of the cell the ray entered,\n"
         "hazier with distance, with outlines where depth jumps; rays that hit nothing show\n"
         "the background.\n"
         "\n"
         "Options:\n"
         "  -o, --output FILE      the picture to write, 8-bit RGB PNG (.png). Written to a\n"
         "                         temporary file beside it and renamed once complete.\n"
         "                         Required.\n"
         "      --eye X Y Z        camera position in metres (default: on the side of the\n"
         "                         occupied cells that shows their longer horizontal extent,\n"
         "                         looking down at "
      << kDefaultElevationDeg
      << " degrees, just far enough away for all\n"
         "                         of them to fit the picture)\n"
         "      --look-at X Y Z    point at the centre of the picture (default: with the\n"
         "                         default eye, the point that centres the occupied cells in\n"
         "                         the picture; with --eye, the centre of their bounding box)\n"
         "      --size WxH         picture size in pixels, each side 1 to "
      << kMaxSide << " (default: " << kDefaultWidth << "x" << kDefaultHeight
      << ")\n"
         "      --fov DEG          vertical field of view in degrees, 1 to 170 (default: "
      << kDefaultFovDeg
      << ")\n"
         "      --z-max Z          hide everything above height Z metres (cut at the cell\n"
         "                         boundary nearest Z), e.g. to look into a building through\n"
         "                         its ceiling (default: nothing hidden)\n";
  printMaxDeviceMemoryHelp(out, "A map or a batch of rays");
  out << "                         Under a cap render counts its picture too ("
      << kPictureBytesPerPixel
      << " bytes a\n"
         "                         pixel) and casts its rays in tiles of rows that fit; a\n"
         "                         --size whose picture does not fit is refused before any\n"
         "                         work, naming the bytes it needs.\n";
  out << "  -h, --help             show this help\n"
         "Options take their value as '--name VALUE' or '--name=VALUE'; --eye and --look-at also\n"
         "as '--eye=X,Y,Z'. Up in the picture is +z (+y when looking straight up or down).\n"
         "\n"
         "Output: the device used, then on stdout the picture size, the camera (eye, look-at,\n"
         "field of view, to repeat or adjust with --eye / --look-at), how many rays hit, the\n"
         "depth range, the time taken and the file written.\n";
}

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
    checkMapInput(in.input(), kRenderUsage);
    in.checkDeviceMemoryCap();
    in.checkOutputs();
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
  std::optional<Vec3> eye_;
  std::optional<Vec3> look_at_;
  std::optional<double> z_max_;
  std::uint32_t width_ = kDefaultWidth;
  std::uint32_t height_ = kDefaultHeight;
  double fov_deg_ = kDefaultFovDeg;
};

int Render::run(Invocation& in) {
  const std::string& map_path = in.input();
  Context& context = in.context();
  const auto start = Clock::now();
  OccupancyMap map = loadMap(context, map_path, in.maxDeviceBytes());
  const double resolution = map.params().resolution;
  const float occupied_log_odds = occupancyLogOdds(map.params());
  // The cells that can show: occupied, and below --z-max, which cuts at the cell boundary
  // nearest it.
  const double z_cut =
      z_max_ ? std::round(*z_max_ / resolution) * resolution : std::numeric_limits<double>::max();
  std::vector<OccupancyMap::LeafBoxHost> shown = map.downloadLeafBoxes();
  std::erase_if(shown, [&](const OccupancyMap::LeafBoxHost& c) {
    return !(c.log_odds >= occupied_log_odds) || c.center[2] - 0.5 * c.size >= z_cut;
  });
  if (shown.empty())
    throw Error(ErrorCode::kInvalidArgument, "map '" + map_path + "' has no occupied cells" +
                                                 (z_max_ ? " below --z-max" : "") +
                                                 ": there is nothing to render");
  Box occupied;
  for (const OccupancyMap::LeafBoxHost& c : shown) occupied.add(c);
  occupied.max.z() = std::min(occupied.max.z(), z_cut);
  const double read_s = secondsSince(start);

  Vec3 look_at = look_at_.value_or(0.5 * (occupied.min + occupied.max));
  Vec3 eye;
  if (eye_) {
    eye = *eye_;
  } else {
    const Vec3 view = defaultView(occupied);
    frame(shown, view, width_, height_, fov_deg_, !look_at_, look_at, eye);
  }
  if ((eye - look_at).norm() < 1e-9)
    throw UsageError("--eye " + vec3Text(eye) + " is the point the camera looks at; move it");
  // castRay needs its origin inside the map: keys 0 … 65535, centred on 0.
  const double domain_m = 32767.0 * resolution;
  if (eye.cwiseAbs().maxCoeff() >= domain_m)
    throw UsageError("--eye " + vec3Text(eye) + " lies outside the map's domain (each coordinate " +
                     "within " + numberText(domain_m) + " m of the origin at this resolution)");
  const Camera camera(eye, look_at, width_, height_, fov_deg_);

  // The memory the rays may take: under a cap, what the map and the picture leave of it.
  const std::size_t pixels = std::size_t{width_} * height_;
  const std::size_t cap = in.maxDeviceBytes();
  std::size_t ray_batch = kRayBatch;
  std::size_t tile_rows = std::max<std::size_t>(1, kTilePixels / width_);
  if (cap > 0) {
    const std::size_t held = map.deviceBytes() + shown.capacity() * sizeof(shown[0]);
    if (leastRenderBytes(width_, height_) + held > cap)
      throw pictureOverCap(width_, height_, cap, held);
    // Half for a tile's rays on the host (and the two rows around it), half for a batch of
    // them on the device.
    const std::size_t room = (cap - held - pixels * kPictureBytesPerPixel) / 2;
    tile_rows =
        std::clamp<std::size_t>(room / (std::size_t{width_} * (sizeof(Sample) + kHostBytesPerRay)),
                                3, tile_rows + 2) -
        2;
    ray_batch = std::clamp<std::size_t>(room / deviceBytesPerRay(), 1, kRayBatch);
  }

  // Nothing outside the occupied cells' box stops a ray that ignores unknown space, so each ray
  // starts where it enters the box and ends where it leaves it: the same first occupied cell as
  // from the eye, without walking the empty space in front (and --z-max is exact this way).
  // The rays are cast in tiles of rows, each shaded once the rows around it are cast; only the
  // colours before the haze and the depths are kept for the whole picture (the haze needs the
  // depth range of all of it).
  double cast_s = 0.0;
  double depth_min = std::numeric_limits<double>::max(), depth_max = 0.0;
  const double z_low = occupied.min.z() + 0.5 * resolution;  // cell centres: z of a hit
  const double z_span = std::max(occupied.max.z() - occupied.min.z() - resolution, resolution);
  // A key light over the camera's left shoulder; faces turned away still get the ambient part.
  const Vec3 light = (-camera.forward * 0.55 - camera.right * 0.4 + Vec3::UnitZ()).normalized();
  const Rgb haze{70, 76, 92};
  const double pixel_angle = 2.0 * camera.tan_half_v / height_;
  RgbImage image(width_, height_);
  std::vector<float> depths(pixels, -1.0f);
  std::vector<Sample> window;  // the samples of rows [window_row, cast_rows)
  std::uint32_t window_row = 0, cast_rows = 0, shaded_rows = 0;
  const auto sample = [&](std::uint32_t x, std::uint32_t y) -> const Sample& {
    return window[std::size_t{y - window_row} * width_ + x];
  };
  std::vector<Ray> rays;
  std::vector<std::size_t> ray_pixel;
  std::vector<double> ray_start;
  std::size_t cast = 0, hits = 0;
  const auto flush = [&] {
    std::vector<RayHit> results;
    for (;;) {
      try {
        results.clear();
        for (std::size_t at = 0; at < rays.size(); at += ray_batch) {
          const std::size_t n = std::min(ray_batch, rays.size() - at);
          const std::vector<RayHit> part = map.castRays(std::span(rays).subspan(at, n));
          results.insert(results.end(), part.begin(), part.end());
        }
        break;
      } catch (const Error& e) {
        // The estimate of a ray's device bytes was short: smaller batches, down to one ray.
        if (e.code() != ErrorCode::kOutOfDeviceMemory || ray_batch == 1) throw withOptionNames(e);
        ray_batch /= 2;
      }
    }
    for (std::size_t i = 0; i < results.size(); ++i) {
      if (!results[i].hit) continue;
      const std::size_t p = ray_pixel[i];
      const Vec3 dir = camera.direction(static_cast<double>(p % width_) + 0.5,
                                        static_cast<double>(p / width_) + 0.5);
      Sample& s = window[p - std::size_t{window_row} * width_];
      s = sampleOf(results[i], eye, dir, resolution, ray_start[i]);
      depth_min = std::min(depth_min, s.depth);
      depth_max = std::max(depth_max, s.depth);
      ++hits;
    }
    cast += rays.size();
    rays.clear();
    ray_pixel.clear();
    ray_start.clear();
  };
  const auto shade = [&](std::uint32_t y) {
    for (std::uint32_t x = 0; x < width_; ++x) {
      const Sample& s = sample(x, y);
      if (s.depth < 0) {
        image.set(x, y, background(y, height_));
        continue;
      }
      Vec3 normal = Vec3::Zero();
      normal[s.axis] = s.normal_sign;
      double light_f = 0.38 + 0.62 * std::max(0.0, normal.dot(light));
      // Cell edges where a cell spans several pixels, so that single voxels can be told apart.
      const double cell_px = resolution / std::max(s.depth * pixel_angle, 1e-12);
      if (cell_px > 5.0) {
        const double edge = 1.0 - 2.4 / cell_px;
        if (std::max(std::abs(s.face_u), std::abs(s.face_v)) > edge) light_f *= 0.72;
      }
      // Outlines where the neighbouring pixel lies much farther away (or is background).
      bool outline = false;
      const auto farther = [&](std::uint32_t nx, std::uint32_t ny) {
        const Sample& n = sample(nx, ny);
        return n.depth < 0 || n.depth > s.depth * 1.04 + 3.0 * resolution;
      };
      if (x > 0 && farther(x - 1, y)) outline = true;
      if (x + 1 < width_ && farther(x + 1, y)) outline = true;
      if (y > 0 && farther(x, y - 1)) outline = true;
      if (y + 1 < height_ && farther(x, y + 1)) outline = true;
      if (outline) light_f *= 0.55;
      image.set(x, y, scale(heightColor((s.z - z_low) / z_span), light_f));
      depths[std::size_t{y} * width_ + x] = static_cast<float>(s.depth);
    }
  };
  double shade_s = 0.0;
  while (shaded_rows < height_) {
    const auto tile_start = Clock::now();
    const std::uint32_t tile_end =
        static_cast<std::uint32_t>(std::min<std::size_t>(height_, cast_rows + tile_rows));
    window.resize(std::size_t{tile_end - window_row} * width_);
    for (std::size_t p = std::size_t{cast_rows} * width_; p < std::size_t{tile_end} * width_; ++p) {
      const Vec3 dir = camera.direction(static_cast<double>(p % width_) + 0.5,
                                        static_cast<double>(p / width_) + 0.5);
      double t_in, t_out;
      if (!occupied.clip(eye, dir, t_in, t_out)) continue;
      // A hair inside the box, so that a start on a cell face lies in the cell behind it.
      if (t_in > 0.0) t_in += 1e-3 * resolution;
      Ray ray;
      ray.origin = (eye + t_in * dir).cast<float>();
      ray.direction = dir.cast<float>();
      ray.max_range_m = t_out - t_in + 2.0 * resolution;
      ray.ignore_unknown = true;
      rays.push_back(ray);
      ray_pixel.push_back(p);
      ray_start.push_back(t_in);
    }
    if (!rays.empty()) flush();
    cast_rows = tile_end;
    const auto shade_start = Clock::now();
    cast_s += std::chrono::duration<double>(shade_start - tile_start).count();
    // A row is shaded once the rows above and below it are cast.
    const std::uint32_t shade_end = cast_rows == height_ ? height_ : cast_rows - 1;
    for (; shaded_rows < shade_end; ++shaded_rows) shade(shaded_rows);
    // The row above the next one to shade stays for its outlines.
    const std::uint32_t keep_from = shaded_rows > 0 ? shaded_rows - 1 : 0;
    window.erase(
        window.begin(),
        window.begin() + static_cast<std::ptrdiff_t>(std::size_t{keep_from - window_row} * width_));
    window_row = keep_from;
    shade_s += secondsSince(shade_start);
  }
  // The haze, now that the depth range is known.
  const auto haze_start = Clock::now();
  for (std::size_t p = 0; p < pixels; ++p) {
    if (depths[p] < 0) continue;
    const std::size_t at = p * 3;
    const Rgb lit{image.pixels[at], image.pixels[at + 1], image.pixels[at + 2]};
    const double far =
        depth_max > depth_min ? (depths[p] - depth_min) / (depth_max - depth_min) : 0;
    image.set(static_cast<std::uint32_t>(p % width_), static_cast<std::uint32_t>(p / width_),
              mix(lit, haze, 0.4 * std::clamp(far, 0.0, 1.0)));
  }
  depths = {};
  shade_s += secondsSince(haze_start);
  const auto write_start = Clock::now();
  in.files().write(0, [&](const std::string& temporary) { writePng(image, temporary); });
  in.files().commit();
  shade_s += secondsSince(write_start);

  const double fov_h_deg = 2.0 * std::atan(camera.tan_half_h) * 180.0 / M_PI;
  char line[512];
  std::ostringstream s;
  s << "device:  " << context.device().name << " (" << context.device().type << ")\n";
  s << "map:     " << map_path << "\n";
  std::snprintf(line, sizeof(line), "image:   %ux%u px\n", width_, height_);
  s << line;
  s << "camera:  --eye " << vec3Text(eye) << " --look-at " << vec3Text(look_at);
  std::snprintf(line, sizeof(line), " --fov %g (vertical; %.1f horizontal)\n", fov_deg_,
                fov_h_deg);
  s << line;
  std::snprintf(line, sizeof(line),
                "rays:    %zu cast (pixels whose ray crosses the occupied cells' box), %zu hit "
                "(%.1f%% of %zu pixels)\n",
                cast, hits, 100.0 * static_cast<double>(hits) / static_cast<double>(pixels),
                pixels);
  s << line;
  if (hits > 0) {
    std::snprintf(line, sizeof(line), "depth:   %.2f to %.2f m\n", depth_min, depth_max);
    s << line;
  }
  std::snprintf(
      line, sizeof(line),
      "time:    %.3f s (reading and upload %.3f s, castRays %.3f s, shading and PNG %.3f s)\n",
      read_s + cast_s + shade_s, read_s, cast_s, shade_s);
  s << line;
  s << "wrote:   " << in.output() << "\n";
  std::cout << s.str() << std::flush;
  return kExitOk;
}

}  // namespace

const Subcommand kRenderCommand{
    .name = "render",
    .print_help = printRenderHelp,
    .input = "map file",
    .second_input_hint = "; the picture goes after -o",
    .outputs = Subcommand::Outputs::kOne,
    .writes = "one picture",
    .no_output = "no output picture; add -o VIEW.png",
    .output_extensions = {".png"},
    .output_formats = ".png",
    .max_device_memory = true,
    .value_options = {"--size", "--fov", "--z-max"},
    .multi_value_options = {{"--eye", "X Y Z"}, {"--look-at", "X Y Z"}},
    .make = []() -> std::unique_ptr<Command> { return std::make_unique<Render>(); },
    .examples =
        "  octovk render map.bt -o view.png\n"
        "  octovk render map.bt -o view.png --eye 10 -10 8 --look-at 0 0 1 --size 1024x768\n"
        "  octovk render map.bt -o inside.png --z-max 2\n"};

}  // namespace octovk::cli
