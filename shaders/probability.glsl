// OctoMap's probability(logodds) = 1 - 1 / (1 + exp(logodds)) in double, the occupancy that
// ColorOcTree::integrateNodeColor weights colours by (getOccupancy of the node's float log-odds).
// GLSL has no double exp, and a Vulkan exp (float only) has no error bound worth the name, so
// exp is built here from the double add, subtract, multiply and divide that the device probe
// checks bit for bit against the host: nothing else of the hardware is used (no fma: Vulkan does
// not promise that GLSL's fma is fused; `precise` on every expression keeps compilers from
// contracting or reassociating).
//
// expCorrectlyRounded(x) is exp(x) rounded to the nearest double, for every double x (a float's
// value in practice):
// - x = k ln2 + r, |r| <= ln2 / 2 (Cody-Waite: ln2 split in three doubles, the first with 32
//   significant bits so that k * ln2_hi and x - k * ln2_hi are exact; r as a double-double);
// - exp(r) - 1 from r / 256 by its Taylor series (terms 1..5 in double-double, 6..10 in double),
//   then squared up eight times as e' = 2e + e^2 (the exp(r) - 1 form keeps e's relative error);
//   all in double-double: Knuth's two-sum, Dekker's two-product with Veltkamp's split, which need
//   only correctly rounded + and *. The error of 1 + e is about 2^-100 relative, so rounding it to
//   double is correct unless exp(r) lies that close to a midpoint between two doubles: expected
//   less than once over all 2^32 floats;
// - the rounded exp(r) scaled by 2^k on its exponent bits (exact); below 2^-1022 rounded once more,
//   on the subnormal grid, from the double-double; above DBL_MAX infinity, below half the least
//   subnormal 0 (glibc's results there).
// glibc's exp, which OctoMap calls, is not correctly rounded (its error bound is about 0.51 ULP)
// and so may differ from this by one ULP in rare inputs; what the colours see is p, where such a
// difference is mostly absorbed by 1 + exp. bench/probability_exhaustive.cpp compares p over every
// float of the default clamping range; docs/benchmarks.md has its count.
// No bindings: device_probe.comp includes it (its kProbeModeProbability, for the tests) as does
// color_fold.comp.
#ifndef OCTOVK_PROBABILITY_GLSL
#define OCTOVK_PROBABILITY_GLSL

double doubleOfBits(uint high, uint low) { return packDouble2x32(uvec2(low, high)); }

// ---- error-free transformations: s + e equals the exact result ----

// Knuth's two-sum: any a, b.
void twoSum(double a, double b, out double s, out double e) {
  precise double sum = a + b;
  precise double b_virtual = sum - a;
  precise double a_virtual = sum - b_virtual;
  precise double err = (a - a_virtual) + (b - b_virtual);
  s = sum;
  e = err;
}

// Dekker's fast two-sum: |a| >= |b| (or a = 0).
void fastTwoSum(double a, double b, out double s, out double e) {
  precise double sum = a + b;
  precise double err = b - (sum - a);
  s = sum;
  e = err;
}

// Veltkamp's split of a into two halves of 26 bits each, a = high + low exactly.
void veltkampSplit(double a, out double high, out double low) {
  precise double c = 134217729.0lf * a;  // 2^27 + 1
  precise double h = c - (c - a);
  precise double l = a - h;
  high = h;
  low = l;
}

// Dekker's two-product: p + e = a * b exactly (no underflow, |a|, |b| far below 2^996).
void twoProduct(double a, double b, out double p, out double e) {
  double ah, al, bh, bl;
  veltkampSplit(a, ah, al);
  veltkampSplit(b, bh, bl);
  precise double product = a * b;
  precise double err = (((ah * bh - product) + ah * bl) + al * bh) + al * bl;
  p = product;
  e = err;
}

// ---- double-double arithmetic (x: high part, y: low part, |y| <= ulp(x) / 2) ----

dvec2 ddAdd(dvec2 a, dvec2 b) {
  double s, e, t, f;
  twoSum(a.x, b.x, s, e);
  twoSum(a.y, b.y, t, f);
  precise double e1 = e + t;
  fastTwoSum(s, e1, s, e);
  precise double e2 = e + f;
  fastTwoSum(s, e2, s, e);
  return dvec2(s, e);
}

dvec2 ddMul(dvec2 a, dvec2 b) {
  double p, e;
  twoProduct(a.x, b.x, p, e);
  precise double cross = a.x * b.y + a.y * b.x;
  precise double e1 = e + cross;
  fastTwoSum(p, e1, p, e);
  return dvec2(p, e);
}

// 1/n! as double-doubles (n = 3, 4, 5) and doubles (n = 6 ... 10), from their bits.
dvec2 inverseFactorialDd(int n) {
  if (n == 3)
    return dvec2(doubleOfBits(0x3FC55555u, 0x55555555u), doubleOfBits(0x3C655555u, 0x55555555u));
  if (n == 4)
    return dvec2(doubleOfBits(0x3FA55555u, 0x55555555u), doubleOfBits(0x3C455555u, 0x55555555u));
  return dvec2(doubleOfBits(0x3F811111u, 0x11111111u), doubleOfBits(0x3C011111u, 0x11111111u));
}

// exp(r) - 1 for |r| <= ln2 / 512, about 2^-104 relative.
dvec2 expm1Reduced(dvec2 r) {
  // Terms 6 ... 10 in double: together below 2^-57 of the result.
  precise double q =
      doubleOfBits(0x3EC71DE3u, 0xA556C734u) + r.x * doubleOfBits(0x3E927E4Fu, 0xB7789F5Cu);
  precise double q8 = doubleOfBits(0x3EFA01A0u, 0x1A01A01Au) + r.x * q;
  precise double q7 = doubleOfBits(0x3F2A01A0u, 0x1A01A01Au) + r.x * q8;
  precise double q6 = doubleOfBits(0x3F56C16Cu, 0x16C16C17u) + r.x * q7;
  dvec2 t = ddAdd(inverseFactorialDd(5), ddMul(r, dvec2(q6, 0.0lf)));
  t = ddAdd(inverseFactorialDd(4), ddMul(r, t));
  t = ddAdd(inverseFactorialDd(3), ddMul(r, t));
  t = ddAdd(dvec2(0.5lf, 0.0lf), ddMul(r, t));
  t = ddAdd(dvec2(1.0lf, 0.0lf), ddMul(r, t));
  return ddMul(r, t);
}

double expCorrectlyRounded(double x) {
  const double kInfinity = doubleOfBits(0x7FF00000u, 0u);
  uvec2 w = unpackDouble2x32(x);
  if ((w.y & 0x7FF00000u) == 0x7FF00000u) {  // decided on the bits (no NaN folding)
    if ((w.y & 0x000FFFFFu) != 0u || w.x != 0u) return x;  // NaN
    return (w.y & 0x80000000u) != 0u ? 0.0lf : x;
  }
  if (x > 710.0lf) return kInfinity;  // exp(709.79) > DBL_MAX already
  if (x < -746.0lf) return 0.0lf;     // exp(-745.14) < 2^-1075 already
  // x = k ln2 + r. ln2 = kLn2Hi + kLn2Mid + kLn2Lo; kLn2Hi has 32 significant bits: k * kLn2Hi
  // is exact for |k| < 2^21, and x - k * kLn2Hi is too (the result needs fewer bits than either).
  const double kInvLn2 = doubleOfBits(0x3FF71547u, 0x652B82FEu);
  const double kLn2Hi = doubleOfBits(0x3FE62E42u, 0xFEE00000u);
  const double kLn2Mid = doubleOfBits(0x3DEA39EFu, 0x35793C76u);
  const double kLn2Lo = doubleOfBits(0x3A8CC01Fu, 0x97B57A08u);
  precise double kd = floor(x * kInvLn2 + 0.5lf);
  int k = int(kd);
  precise double t1 = x - kd * kLn2Hi;
  double p2, p2_err;
  twoProduct(kd, kLn2Mid, p2, p2_err);
  precise double p3 = kd * kLn2Lo;
  precise double minus_p2 = -p2;
  double rh, rl;
  twoSum(t1, minus_p2, rh, rl);
  precise double rl2 = (rl - p2_err) - p3;
  fastTwoSum(rh, rl2, rh, rl);
  // exp(r) = (1 + expm1(r / 256))^256, squared up in the exp - 1 form.
  precise double sh = rh * 0.00390625lf;
  precise double sl = rl * 0.00390625lf;
  dvec2 e = expm1Reduced(dvec2(sh, sl));
  for (int i = 0; i < 8; ++i) {
    precise double twice_h = e.x + e.x;
    precise double twice_l = e.y + e.y;
    e = ddAdd(dvec2(twice_h, twice_l), ddMul(e, e));
  }
  double h, l, t;
  twoSum(1.0lf, e.x, h, t);
  precise double t2 = t + e.y;
  fastTwoSum(h, t2, h, l);  // h: exp(r) rounded to nearest; h + l: exp(r) to about 2^-100
  // Times 2^k on the exponent bits where the result is a normal double.
  uvec2 hb = unpackDouble2x32(h);
  int biased = int((hb.y >> 20) & 0x7FFu) + k;
  if (biased >= 0x7FF) return kInfinity;
  if (biased >= 1) return packDouble2x32(uvec2(hb.x, (hb.y & 0x800FFFFFu) | (uint(biased) << 20)));
  // Subnormal: round (h + l) * 2^(k + 1074) to an integer n (ties to even), the result n * 2^-1074.
  // k + 1074 is in [-3, 52] here: the scalings by it are exact, a normal double times a power of 2.
  precise double scale = doubleOfBits(uint(k + 1074 + 1023) << 20, 0u);
  precise double a = h * scale;
  precise double lo = l * scale;
  precise double n0 = floor(a);
  precise double frac = a - n0;  // exact
  // Its sign is that of frac + lo - 1/2 (frac - 1/2 is exact where it can be near lo's size).
  precise double d = (frac - 0.5lf) + lo;
  precise double half_n0 = n0 * 0.5lf;
  bool odd = floor(half_n0) != half_n0;
  precise double n = (d > 0.0lf || (d == 0.0lf && odd)) ? n0 + 1.0lf : n0;
  // n + 2^52 holds n in its 52 fraction bits (n <= 2^52: 2^53 gives 2^-1022, the least normal).
  precise double biased_n = n + 4503599627370496.0lf;
  uvec2 nb = unpackDouble2x32(biased_n);
  return packDouble2x32(uvec2(nb.x, nb.y - 0x43300000u));
}

// octomap::probability(log_odds): the node's occupancy as integrateNodeColor reads it.
double occupancyProbability(float log_odds) {
  precise double e = expCorrectlyRounded(double(log_odds));
  precise double denominator = 1.0lf + e;
  precise double inverse = 1.0lf / denominator;
  precise double p = 1.0lf - inverse;
  return p;
}

#endif  // OCTOVK_PROBABILITY_GLSL
