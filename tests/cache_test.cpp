// What octovk keeps between runs (the device probe's verdict, the Vulkan pipeline cache) is only
// a shortcut: a missing, truncated, corrupt or foreign file, a folder that cannot be written, or
// OCTOVK_PIPELINE_CACHE=0 never changes a map or fails a call. Every test points the cache folder
// at its own scratch folder (OCTOVK_CACHE_DIR), never at the user's.
#include <sys/stat.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "map/context_access.hpp"
#include "map/device_probe.hpp"
#include "test_support.hpp"
#include "vk/device.hpp"
#include "vk/disk_cache.hpp"
#include "vk/pipeline_cache.hpp"

namespace octovk {
namespace {

namespace fs = std::filesystem;
using test::fileBytes;
using test::writeBytes;

// Each test's own cache folder, emptied, and the variables this file sets, restored after.
class CacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(test::tmpPath("cache_test")) /
           (std::string(info->test_suite_name()) + "." + info->name());
    fs::remove_all(dir_);
    for (const char* name : kVariables) {
      const char* value = std::getenv(name);
      saved_.emplace_back(value ? std::optional<std::string>(value) : std::nullopt);
    }
    ::setenv("OCTOVK_CACHE_DIR", dir_.c_str(), 1);
    ::unsetenv("OCTOVK_PIPELINE_CACHE");
    ::unsetenv("OCTOVK_REPROBE");
  }
  void TearDown() override {
    for (std::size_t i = 0; i < std::size(kVariables); ++i) {
      if (saved_[i])
        ::setenv(kVariables[i], saved_[i]->c_str(), 1);
      else
        ::unsetenv(kVariables[i]);
    }
  }

  // A fresh Context (its own device, probe and pipelines), or nullptr after failing or skipping.
  std::unique_ptr<Context> freshContext() {
    ContextOptions options;
    options.on_validation_message = [](const std::string& message) {
      ADD_FAILURE() << "Vulkan validation " << message;
    };
    auto result = Context::create(options);
    if (!result) {
      if (test::runningInCi())
        ADD_FAILURE() << "no Vulkan device under CI: " << result.error().what();
      return nullptr;
    }
    return std::move(result.value());
  }

  static constexpr const char* kVariables[] = {"OCTOVK_CACHE_DIR", "OCTOVK_PIPELINE_CACHE",
                                               "OCTOVK_REPROBE", "XDG_CACHE_HOME", "HOME"};
  fs::path dir_;
  std::vector<std::optional<std::string>> saved_;
};

#define OCTOVK_FRESH_CONTEXT(ctx)                                   \
  std::unique_ptr<Context> ctx##_owner = freshContext();            \
  if (!ctx##_owner) {                                               \
    if (test::runningInCi()) FAIL() << "no Vulkan device under CI"; \
    GTEST_SKIP() << "no Vulkan device";                             \
  }                                                                 \
  Context& ctx = *ctx##_owner

// A scan into a fresh map of `ctx`, against OctoMap's map of the same scan.
::testing::AssertionResult scanEqualsOctoMap(Context& ctx) {
  std::mt19937 rng(7);
  const Eigen::Vector3f origin(0.3f, -0.2f, 0.1f);
  const auto points = test::randomScan(rng, origin, 3000, 4.0f);
  const MapParams params = test::withResolution(0.1);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = test::makeOracle(params);
  return test::insertBoth(map, oracle, points, origin, -1.0, false);
}

std::span<const std::byte> bytesOf(const std::string& s) {
  return std::as_bytes(std::span(s.data(), s.size()));
}

TEST_F(CacheTest, RecordsRoundTripAndEveryDamagedOrForeignCopyReadsAsNothing) {
  const fs::path file = dir_ / "record.bin";
  const std::string key = "device x; driver y; octovk shaders z";
  const std::string payload = "the payload \x01\x02\x03";
  ASSERT_TRUE(vk::disk::writeRecord(file, "probe", key, bytesOf(payload)));
  auto back = vk::disk::readRecord(file, "probe", key);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(back->data()), back->size()), payload);
  EXPECT_EQ((fs::status(dir_).permissions() & fs::perms::all), fs::perms::owner_all)
      << "the cache folder is the user's own";

  EXPECT_FALSE(vk::disk::readRecord(file, "probe", key + " ").has_value()) << "another key";
  EXPECT_FALSE(vk::disk::readRecord(file, "pipeline", key).has_value()) << "another kind";
  EXPECT_FALSE(vk::disk::readRecord(dir_ / "missing.bin", "probe", key).has_value());

  const std::string whole = fileBytes(file.string());
  const fs::path damaged = dir_ / "damaged.bin";
  for (std::size_t n = 0; n < whole.size(); ++n) {
    writeBytes(damaged.string(), whole.substr(0, n));
    EXPECT_FALSE(vk::disk::readRecord(damaged, "probe", key).has_value()) << "cut to " << n;
  }
  writeBytes(damaged.string(), whole + "x");
  EXPECT_FALSE(vk::disk::readRecord(damaged, "probe", key).has_value()) << "one byte more";
  for (std::size_t i = 0; i < whole.size(); ++i) {
    std::string flipped = whole;
    flipped[i] = static_cast<char>(flipped[i] ^ 0x10);
    writeBytes(damaged.string(), flipped);
    EXPECT_FALSE(vk::disk::readRecord(damaged, "probe", key).has_value()) << "byte " << i;
  }
}

TEST_F(CacheTest, WritingWhereNoFolderCanBeMadeFailsQuietly) {
  fs::create_directories(dir_);
  writeBytes((dir_ / "a-file").string(), "not a folder");
  // Even root cannot make a folder under a regular file.
  const fs::path blocked = dir_ / "a-file" / "octovk" / "record.bin";
  EXPECT_FALSE(vk::disk::writeRecord(blocked, "probe", "key", bytesOf("x")));
  EXPECT_FALSE(vk::disk::readRecord(blocked, "probe", "key").has_value());
  EXPECT_FALSE(vk::disk::writeRecord({}, "probe", "key", bytesOf("x")));
  EXPECT_EQ(fileBytes((dir_ / "a-file").string()), "not a folder");
  for (const auto& entry : fs::directory_iterator(dir_))
    EXPECT_EQ(entry.path().filename(), "a-file") << "a temporary file was left behind";
}

TEST_F(CacheTest, FolderIsOctovkCacheDirElseXdgCacheHomeElseHome) {
  EXPECT_EQ(vk::disk::folder(), dir_);
  ::unsetenv("OCTOVK_CACHE_DIR");
  ::setenv("XDG_CACHE_HOME", "/xdg/cache", 1);
  ::setenv("HOME", "/home/someone", 1);
  EXPECT_EQ(vk::disk::folder(), fs::path("/xdg/cache/octovk"));
  ::setenv("XDG_CACHE_HOME", "relative/cache", 1);  // the XDG spec: ignored when relative
  EXPECT_EQ(vk::disk::folder(), fs::path("/home/someone/.cache/octovk"));
  ::unsetenv("XDG_CACHE_HOME");
  ::unsetenv("HOME");
  EXPECT_TRUE(vk::disk::folder().empty()) << "nowhere to keep anything";
}

TEST_F(CacheTest, CacheKeyNamesTheDeviceTheDriverAndTheBuild) {
  OCTOVK_FRESH_CONTEXT(ctx);
  vk::Device& device = ContextAccess::device(ctx);
  const std::string& key = device.cacheKey();
  EXPECT_NE(key.find(device.properties().deviceName), std::string::npos) << key;
  EXPECT_NE(key.find("uuid"), std::string::npos) << key;
  EXPECT_NE(key.find("pipeline cache uuid"), std::string::npos) << key;
  EXPECT_NE(key.find("octovk shaders"), std::string::npos) << key;
  EXPECT_EQ(device.cacheFile("probe").parent_path(), dir_);
  ::unsetenv("OCTOVK_CACHE_DIR");
  ::unsetenv("XDG_CACHE_HOME");
  ::unsetenv("HOME");
  EXPECT_TRUE(device.cacheFile("probe").empty());
}

TEST_F(CacheTest, ProbeVerdictIsKeptAndEqualsAFreshProbe) {
  OCTOVK_FRESH_CONTEXT(ctx);
  vk::Device& device = ContextAccess::device(ctx);
  ASSERT_TRUE(fs::exists(device.cacheFile("probe"))) << "the first Context keeps its verdict";
  auto kept = checkDevice(device);
  ASSERT_TRUE(kept) << kept.error().what();
  EXPECT_TRUE(kept.value().kept);
  auto fresh = probeDevice(device);
  ASSERT_TRUE(fresh) << fresh.error().what();
  EXPECT_FALSE(fresh.value().kept);
  EXPECT_EQ(kept.value().loop_limit, fresh.value().loop_limit);

  ::setenv("OCTOVK_REPROBE", "1", 1);
  auto again = checkDevice(device);
  ASSERT_TRUE(again) << again.error().what();
  EXPECT_FALSE(again.value().kept) << "OCTOVK_REPROBE=1 probes again";
  EXPECT_EQ(again.value().loop_limit, fresh.value().loop_limit);
  ::unsetenv("OCTOVK_REPROBE");
  EXPECT_TRUE(scanEqualsOctoMap(ctx));
}

TEST_F(CacheTest, DamagedOrForeignProbeRecordsAreNeverTrusted) {
  OCTOVK_FRESH_CONTEXT(first);
  vk::Device& device = ContextAccess::device(first);
  const fs::path file = device.cacheFile("probe");
  const std::string good = fileBytes(file.string());
  ASSERT_FALSE(good.empty());
  // A verdict that, if trusted, would refuse the device (a loop limit of 1) or change its walk.
  const std::uint32_t lying[2] = {1u, 1u};
  const std::span<const std::byte> lie = std::as_bytes(std::span(lying));
  const std::string foreign_key = device.cacheKey() + "; probe 0";
  const std::vector<std::pair<std::string, std::function<void()>>> variants = {
      {"garbage", [&] { writeBytes(file.string(), "not a record at all"); }},
      {"truncated", [&] { writeBytes(file.string(), good.substr(0, good.size() - 3)); }},
      {"empty", [&] { writeBytes(file.string(), ""); }},
      {"another key", [&] { vk::disk::writeRecord(file, "probe", foreign_key, lie); }},
      {"a folder in its place",
       [&] {
         fs::remove(file);
         fs::create_directories(file / "x");
       }},
  };
  for (const auto& [what, damage] : variants) {
    SCOPED_TRACE(what);
    damage();
    auto verdict = checkDevice(device);
    ASSERT_TRUE(verdict) << verdict.error().what();
    EXPECT_FALSE(verdict.value().kept);
    EXPECT_NE(verdict.value().loop_limit, 1u);
    // A fresh Context after the damage works and maps as OctoMap does.
    OCTOVK_FRESH_CONTEXT(ctx);
    EXPECT_TRUE(scanEqualsOctoMap(ctx));
    if (fs::is_directory(file)) {
      fs::remove_all(file);
    } else {
      auto kept = checkDevice(device);
      ASSERT_TRUE(kept);
      EXPECT_TRUE(kept.value().kept) << "the probe's verdict replaced the bad record";
    }
  }
}

// The driver's own data for this device: what an empty VkPipelineCache gives (the header Vulkan
// defines, and whatever the driver adds).
std::vector<std::byte> emptyCacheData(vk::Device& device) {
  VkPipelineCacheCreateInfo info{VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO};
  VkPipelineCache cache;
  EXPECT_EQ(vkCreatePipelineCache(device.handle(), &info, nullptr, &cache), VK_SUCCESS);
  std::size_t size = 0;
  vkGetPipelineCacheData(device.handle(), cache, &size, nullptr);
  std::vector<std::byte> data(size);
  vkGetPipelineCacheData(device.handle(), cache, &size, data.data());
  vkDestroyPipelineCache(device.handle(), cache, nullptr);
  data.resize(size);
  return data;
}

TEST_F(CacheTest, PipelineCacheLoadsOnlyThisDriversOwnData) {
  OCTOVK_FRESH_CONTEXT(ctx);
  vk::Device& device = ContextAccess::device(ctx);
  const std::vector<std::byte> own = emptyCacheData(device);
  ASSERT_GE(own.size(), sizeof(VkPipelineCacheHeaderVersionOne));
  const fs::path file = dir_ / "pipelines-test.bin";
  const std::string key = device.cacheKey();
  auto load = [&] {
    vk::PipelineCache cache(device.handle(), device.properties(), file, key);
    EXPECT_NE(cache.handle(), VK_NULL_HANDLE);
    return cache.loadedBytes();
  };
  ASSERT_TRUE(vk::disk::writeRecord(file, "pipeline", key, own));
  EXPECT_EQ(load(), own.size()) << "the driver's own data is loaded";

  auto withHeader = [&](auto change) {
    std::vector<std::byte> data = own;
    VkPipelineCacheHeaderVersionOne h;
    std::memcpy(&h, data.data(), sizeof h);
    change(h);
    std::memcpy(data.data(), &h, sizeof h);
    return data;
  };
  const std::vector<std::pair<std::string, std::vector<std::byte>>> foreign = {
      {"another vendor", withHeader([](auto& h) { h.vendorID ^= 1u; })},
      {"another device", withHeader([](auto& h) { h.deviceID ^= 1u; })},
      {"another pipelineCacheUUID", withHeader([](auto& h) { h.pipelineCacheUUID[3] ^= 1u; })},
      {"another header version",
       withHeader([](auto& h) { h.headerVersion = static_cast<VkPipelineCacheHeaderVersion>(7); })},
      {"a header longer than the data",
       withHeader([&](auto& h) { h.headerSize = static_cast<std::uint32_t>(own.size() + 1); })},
      {"shorter than a header",
       std::vector<std::byte>(own.begin(),
                              own.begin() + sizeof(VkPipelineCacheHeaderVersionOne) - 1)},
  };
  for (const auto& [what, data] : foreign) {
    SCOPED_TRACE(what);
    ASSERT_TRUE(vk::disk::writeRecord(file, "pipeline", key, data));
    EXPECT_EQ(load(), 0u);
  }
  ASSERT_TRUE(vk::disk::writeRecord(file, "pipeline", key + "x", own));
  EXPECT_EQ(load(), 0u) << "another build's record";
  writeBytes(file.string(), "garbage");
  EXPECT_EQ(load(), 0u);
  fs::remove(file);
  EXPECT_EQ(load(), 0u);
}

TEST_F(CacheTest, PipelineCacheFilesNeverChangeTheMapOrFailTheCall) {
  const std::string scratch = (dir_ / "scratch").string();
  std::string file;  // the pipeline cache file of this device, found with the first Context
  {
    OCTOVK_FRESH_CONTEXT(ctx);
    EXPECT_TRUE(scanEqualsOctoMap(ctx));
    vk::Device& device = ContextAccess::device(ctx);
    EXPECT_TRUE(device.usesPipelineCache());
    file = device.cacheFile("pipelines").string();
  }
  // Whatever the driver kept (lavapipe keeps nothing, a GPU driver its compiled shaders).
  const std::string kept = fileBytes(file);
  std::string record;
  {
    OCTOVK_FRESH_CONTEXT(ctx);
    vk::Device& device = ContextAccess::device(ctx);
    const std::vector<std::byte> own = emptyCacheData(device);
    vk::disk::writeRecord(scratch, "pipeline", device.cacheKey(), own);
    record = fileBytes(scratch);
    ASSERT_FALSE(record.empty());
  }
  const std::vector<std::pair<std::string, std::function<void()>>> variants = {
      {"as kept",
       [&] {
         if (!kept.empty()) writeBytes(file, kept);
       }},
      {"garbage", [&] { writeBytes(file, std::string(4096, '\x5a')); }},
      {"truncated", [&] { writeBytes(file, record.substr(0, record.size() / 2)); }},
      {"empty", [&] { writeBytes(file, ""); }},
      {"the driver's own header", [&] { writeBytes(file, record); }},
      {"one byte changed",
       [&] {
         std::string r = record;
         r[r.size() - 8] = static_cast<char>(r[r.size() - 8] ^ 1);
         writeBytes(file, r);
       }},
      {"a folder in its place",
       [&] {
         fs::remove(file);
         fs::create_directories(fs::path(file) / "x");
       }},
      {"no folder can be made",
       [&] {
         writeBytes((dir_ / "a-file").string(), "x");
         ::setenv("OCTOVK_CACHE_DIR", (dir_ / "a-file" / "cache").c_str(), 1);
       }},
      {"OCTOVK_PIPELINE_CACHE=0",
       [&] {
         writeBytes(file, std::string(64, '\x01'));
         ::setenv("OCTOVK_PIPELINE_CACHE", "0", 1);
       }},
  };
  for (const auto& [what, prepare] : variants) {
    SCOPED_TRACE(what);
    prepare();
    const std::string before = fs::is_regular_file(file) ? fileBytes(file) : std::string();
    {
      OCTOVK_FRESH_CONTEXT(ctx);
      EXPECT_TRUE(scanEqualsOctoMap(ctx));
      EXPECT_EQ(ContextAccess::device(ctx).usesPipelineCache(), what != "OCTOVK_PIPELINE_CACHE=0");
    }
    if (what == "OCTOVK_PIPELINE_CACHE=0") {
      EXPECT_EQ(fileBytes(file), before) << "the file is left alone";
    }
    ::setenv("OCTOVK_CACHE_DIR", dir_.c_str(), 1);
    ::unsetenv("OCTOVK_PIPELINE_CACHE");
    if (fs::is_directory(file)) fs::remove_all(file);
  }
}

}  // namespace
}  // namespace octovk
