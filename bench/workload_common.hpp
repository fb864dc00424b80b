// What the workloads share: their maps, repetitions and medians, and the Markdown tables most of
// them print (paper.cpp, scan_dat.cpp, fr079.cpp, scaling.cpp; queries.cpp keeps its own).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "json.hpp"
#include "measure.hpp"
#include "octovk/octovk.hpp"
#include "workloads.hpp"

namespace octovk::bench {

using Clock = std::chrono::steady_clock;

/// The paper's view size, in rays.
constexpr std::size_t kPaperWidth = 320;
constexpr std::size_t kPaperHeight = 240;

double secondsSince(Clock::time_point start);

/// --resolution's list, else the workload's `full` list, or its `quick` one with --quick.
std::vector<double> resolutionsFor(const BenchOptions& o, std::vector<double> full,
                                   std::vector<double> quick);

/// A fresh map at `resolution` with OctoMap's defaults and the options' leaf-box setting.
OccupancyMap makeMap(Context& context, const BenchOptions& o, double resolution,
                     ScanRays rays = ScanRays::kWalk);

double median(std::vector<double> v);

/// Field-wise mean of several scans (for "per view" rows and Table I).
ScanTiming meanOf(const std::vector<ScanTiming>& scans);

double perSecond(double count, double ms);

/// printf of one number into a string.
std::string fmt(const char* format, double v);

/// Scans whose cell sets differ in size between OctoMap and octovk (before early abort).
int cellMismatches(const std::vector<ScanTiming>& scans);

/// Per scan: rays, cells, OctoMap's and octovk's times and rates.
void printScanTable(const std::string& first_column, const std::vector<std::string>& labels,
                    const std::vector<ScanTiming>& scans);
/// Per scan: octovk's device time per stage.
void printStageTable(const std::string& first_column, const std::vector<std::string>& labels,
                     const std::vector<ScanTiming>& scans);
/// The paper's Table I: one column per resolution, mean per view, milliseconds.
void printTableOne(const std::vector<double>& resolutions, const std::vector<ScanTiming>& means);

void writeScans(JsonWriter& json, const std::vector<ScanTiming>& scans);

/// Runs `scans` in order into fresh maps, `repeat` times; per scan the median of the times.
std::vector<ScanTiming> repeatSequence(
    int repeat, const std::function<std::vector<ScanTiming>(int rep)>& run_once);

/// A line on stderr, at once.
void progress(const char* format, auto... args) {
  std::fprintf(stderr, format, args...);
  std::fflush(stderr);
}

}  // namespace octovk::bench
