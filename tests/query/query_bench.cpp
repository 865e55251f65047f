// The queries' benchmark (scripts/bench --only queries): rays, boxes and nearest points through a
// cluster file's hierarchy, and the same rays through Embree (Debian's libembree-dev, 3.13:
// rtcIntersect1 and rtcOccluded1 over a scene of the file's triangles built at medium quality).
// Embree is the peer of the benchmark alone: the library never links it.
//
//   query_bench FILE.fch [--rays N] [--queries N] [--threads T] [--repeat R] [--prefix F]
//               [--embree] [--reader-memory BYTES [--batch N] [--load-rays PREFIX]] [--only rays|all]
//               [--save-rays PREFIX]
//
// Camera rays: a pinhole camera outside the bounding sphere looking at its centre, sqrt(N) x
// sqrt(N) pixels over the sphere. Random rays: origins uniform in the box grown by a tenth of its
// diagonal, directions uniform on the sphere. --prefix keeps the first F of the nodes (a truncated
// file: its cut-off children are leaves whose faces are tested). With --reader-memory the rays go
// through a ClusterFileReader under that cap instead of the file in memory, N at a time (65,536 by
// default), as a consumer streaming its rays would send them, and are timed once. --save-rays
// writes the rays of the file in memory to PREFIX.camera and PREFIX.random (float32 origin x, y, z
// and direction x, y, z per ray), and the boxes and points to PREFIX.boxes and PREFIX.points, for
// the same queries through Python; --load-rays sends those rays through the reader instead of
// rays framing its root's box. Every timing is the
// median of R runs, facetree and Embree alternating. Prints one JSON object.
#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include "facetree/io.h"
#include "facetree/query.h"

namespace {

using facetree::ClusterFile;
using facetree::QueryStats;
using facetree::Ray;
using facetree::RayHit;
using Clock = std::chrono::steady_clock;

struct Args {
  std::string file;
  uint64_t rays = 1 << 20, queries = 1 << 16;
  unsigned threads = 1, repeat = 3;
  double prefix = 1.0;
  bool embree = false, raysOnly = false;
  uint64_t readerMemory = 0, batch = 1 << 16;
  std::string saveRays;  // PREFIX: the rays traced, as PREFIX.camera and PREFIX.random
  std::string loadRays;  // PREFIX: through the reader, the rays a --save-rays run wrote
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(s + " needs a value");
      return argv[++i];
    };
    if (s == "--rays")
      a.rays = std::stoull(value());
    else if (s == "--queries")
      a.queries = std::stoull(value());
    else if (s == "--threads")
      a.threads = unsigned(std::stoul(value()));
    else if (s == "--repeat")
      a.repeat = std::max(1u, unsigned(std::stoul(value())));
    else if (s == "--prefix")
      a.prefix = std::stod(value());
    else if (s == "--embree")
      a.embree = true;
    else if (s == "--reader-memory")
      a.readerMemory = std::stoull(value());
    else if (s == "--batch")
      a.batch = std::max<uint64_t>(1, std::stoull(value()));
    else if (s == "--save-rays")
      a.saveRays = value();
    else if (s == "--load-rays")
      a.loadRays = value();
    else if (s == "--only")
      a.raysOnly = value() == "rays";
    else if (a.file.empty() && s[0] != '-')
      a.file = s;
    else
      throw std::invalid_argument("unknown argument " + s);
  }
  if (a.file.empty()) throw std::invalid_argument("usage: query_bench FILE.fch [options]");
  return a;
}

double seconds(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// A float in [0, 1) from 24 bits, the same on every platform (std's distributions are not).
float unit(std::mt19937_64& rng) {
  return float(rng() >> 40) * (1.0f / 16777216.0f);
}

glm::vec3 onSphere(std::mt19937_64& rng) {
  const float z = 2.0f * unit(rng) - 1.0f, phi = 6.28318530718f * unit(rng);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

struct Bounds {
  glm::vec3 lo{0.0f}, hi{0.0f};
  glm::vec3 centre() const { return 0.5f * (lo + hi); }
  float diagonal() const { return glm::length(hi - lo); }
};

Bounds bounds(const std::vector<glm::vec3>& v) {
  Bounds b{v.empty() ? glm::vec3(0.0f) : v[0], v.empty() ? glm::vec3(0.0f) : v[0]};
  for (const glm::vec3& p : v) {
    b.lo = glm::min(b.lo, p);
    b.hi = glm::max(b.hi, p);
  }
  return b;
}

// Camera rays [begin, end) of the sqrt(n) x sqrt(n) picture, in scan order.
std::vector<Ray> cameraRays(const Bounds& b, uint64_t n, uint64_t begin = 0, uint64_t end = UINT64_MAX) {
  const auto side = uint32_t(std::max(1.0, std::floor(std::sqrt(double(n)))));
  const glm::vec3 centre = b.centre(), view = glm::normalize(glm::vec3(-0.55f, -0.35f, -0.76f));
  const float radius = 0.5f * b.diagonal();
  const glm::vec3 eye = centre - 3.0f * radius * view;
  const glm::vec3 right = glm::normalize(glm::cross(view, glm::vec3(0.0f, 1.0f, 0.0f)));
  const glm::vec3 up = glm::cross(right, view);
  const float half = radius / (3.0f * radius) * 1.05f;  // the sphere's half angle, a margin
  end = std::min<uint64_t>(end, uint64_t(side) * side);
  std::vector<Ray> rays;
  rays.reserve(end > begin ? end - begin : 0);
  for (uint64_t k = begin; k < end; ++k) {
    const auto x = uint32_t(k % side), y = uint32_t(k / side);
    const float sx = ((float(x) + 0.5f) / float(side) * 2.0f - 1.0f) * half;
    const float sy = ((float(y) + 0.5f) / float(side) * 2.0f - 1.0f) * half;
    rays.push_back({eye, glm::normalize(view + sx * right + sy * up)});
  }
  return rays;
}

uint64_t cameraRayCount(uint64_t n) {
  const auto side = uint64_t(std::max(1.0, std::floor(std::sqrt(double(n)))));
  return side * side;
}

// The next n random rays from `rng`: successive calls continue one sequence.
std::vector<Ray> randomRays(const Bounds& b, uint64_t n, std::mt19937_64& rng) {
  const glm::vec3 grow(0.1f * b.diagonal());
  const glm::vec3 lo = b.lo - grow, size = (b.hi + grow) - lo;
  std::vector<Ray> rays(n);
  for (Ray& r : rays) {
    r.origin = lo + glm::vec3(unit(rng), unit(rng), unit(rng)) * size;
    r.direction = onSphere(rng);
  }
  return rays;
}

std::vector<Ray> randomRays(const Bounds& b, uint64_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  return randomRays(b, n, rng);
}

// Runs f(begin, end) over blocks of `count` on `threads` threads.
void parallelBlocks(size_t count, unsigned threads, const std::function<void(size_t, size_t)>& f) {
  constexpr size_t kBlock = 1024;
  std::atomic<size_t> next{0};
  const auto work = [&] {
    for (size_t b; (b = next.fetch_add(kBlock)) < count;) f(b, std::min(count, b + kBlock));
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

struct EmbreeScene {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  double buildSeconds = 0;
  EmbreeScene(const ClusterFile& f, unsigned threads) {
    const std::string config = "threads=" + std::to_string(threads) + ",set_affinity=0";
    device = rtcNewDevice(config.c_str());
    if (!device) throw std::runtime_error("rtcNewDevice failed");
    const auto start = Clock::now();
    scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), f.vertices.size()));
    std::memcpy(v, f.vertices.data(), f.vertices.size() * sizeof(glm::vec3));
    auto* i = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                             3 * sizeof(unsigned), f.indices.size() / 3));
    std::memcpy(i, f.indices.data(), f.indices.size() * sizeof(uint32_t));
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene);
    buildSeconds = seconds(start);
  }
  ~EmbreeScene() {
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
  }
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  static RTCRay ray(const Ray& r) {
    RTCRay e{};
    e.org_x = r.origin.x, e.org_y = r.origin.y, e.org_z = r.origin.z;
    e.dir_x = r.direction.x, e.dir_y = r.direction.y, e.dir_z = r.direction.z;
    e.tnear = r.tMin;
    e.tfar = r.tMax;
    e.mask = ~0u;
    return e;
  }
  std::vector<RayHit> intersect(const std::vector<Ray>& rays, unsigned threads) const {
    std::vector<RayHit> hits(rays.size());
    parallelBlocks(rays.size(), threads, [&](size_t begin, size_t end) {
      RTCIntersectContext context;
      rtcInitIntersectContext(&context);
      for (size_t k = begin; k < end; ++k) {
        RTCRayHit h{};
        h.ray = ray(rays[k]);
        h.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene, &context, &h);
        if (h.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
          hits[k].t = h.ray.tfar;
          hits[k].face = h.hit.primID;
          hits[k].u = h.hit.u;
          hits[k].v = h.hit.v;
        }
      }
    });
    return hits;
  }
  std::vector<uint8_t> occluded(const std::vector<Ray>& rays, unsigned threads) const {
    std::vector<uint8_t> out(rays.size());
    parallelBlocks(rays.size(), threads, [&](size_t begin, size_t end) {
      RTCIntersectContext context;
      rtcInitIntersectContext(&context);
      for (size_t k = begin; k < end; ++k) {
        RTCRay r = ray(rays[k]);
        rtcOccluded1(scene, &context, &r);
        out[k] = r.tfar < 0.0f;
      }
    });
    return out;
  }
};

// The rays through facetree: the file in memory, or a reader's query index under its cap.
struct Tracer {
  const facetree::RayLayout* layout = nullptr;
  facetree::ReaderQueryIndex* index = nullptr;
  std::vector<RayHit> intersect(const std::vector<Ray>& rays, unsigned threads, QueryStats* s) const {
    const facetree::QueryOptions o{threads};
    return index ? facetree::intersect(*index, rays, o, s) : facetree::intersect(*layout, rays, o, s);
  }
  std::vector<uint8_t> occluded(const std::vector<Ray>& rays, unsigned threads, QueryStats* s) const {
    const facetree::QueryOptions o{threads};
    return index ? facetree::occluded(*index, rays, o, s) : facetree::occluded(*layout, rays, o, s);
  }
};

std::string number(double v) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

double relative(double a, double b) {
  return std::abs(a - b) / std::max(1e-30, std::abs(b));
}

// The t at which the ray meets the plane of triangle `face`, in long double.
double exactT(const ClusterFile& f, const Ray& r, uint64_t face) {
  using V = long double;
  V p[3][3];
  for (int c = 0; c < 3; ++c)
    for (int k = 0; k < 3; ++k) p[c][k] = f.vertices[f.indices[3 * face + uint64_t(c)]][k];
  V e1[3], e2[3], n[3];
  for (int k = 0; k < 3; ++k) e1[k] = p[1][k] - p[0][k], e2[k] = p[2][k] - p[0][k];
  n[0] = e1[1] * e2[2] - e1[2] * e2[1];
  n[1] = e1[2] * e2[0] - e1[0] * e2[2];
  n[2] = e1[0] * e2[1] - e1[1] * e2[0];
  V num = 0, den = 0;
  for (int k = 0; k < 3; ++k) {
    num += n[k] * (p[0][k] - V(r.origin[k]));
    den += n[k] * V(r.direction[k]);
  }
  return double(num / den);
}

// The t at which the ray meets triangle `face` in long double, where the exact barycentrics lie in
// the triangle (edges included), else infinity: which of two answers is the true nearest hit.
long double exactHit(const ClusterFile& f, const Ray& r, uint64_t face) {
  using V = long double;
  V p[3][3], o[3], d[3];
  for (int c = 0; c < 3; ++c)
    for (int k = 0; k < 3; ++k) p[c][k] = f.vertices[f.indices[3 * face + uint64_t(c)]][k];
  for (int k = 0; k < 3; ++k) o[k] = r.origin[k], d[k] = r.direction[k];
  const auto cross = [](const V* a, const V* b, V* out) {
    out[0] = a[1] * b[2] - a[2] * b[1], out[1] = a[2] * b[0] - a[0] * b[2],
    out[2] = a[0] * b[1] - a[1] * b[0];
  };
  const auto dot = [](const V* a, const V* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  V e1[3], e2[3], s[3], pv[3], qv[3];
  for (int k = 0; k < 3; ++k) e1[k] = p[1][k] - p[0][k], e2[k] = p[2][k] - p[0][k], s[k] = o[k] - p[0][k];
  cross(d, e2, pv);
  const V det = dot(e1, pv);
  const V inf = std::numeric_limits<V>::infinity();
  if (det == 0) return inf;
  const V u = dot(s, pv) / det;
  cross(s, e1, qv);
  const V v = dot(d, qv) / det;
  if (u < 0 || v < 0 || u + v > 1) return inf;
  const V t = dot(e2, qv) / det;
  return t >= r.tMin && t <= r.tMax ? t : inf;
}

// A batch's object, opened: its rays and hits, the closest and any hits' times, and the boxes and
// triangles tested a ray.
std::string rayFields(const char* name, uint64_t rays, uint64_t hit, double closest, double any,
                      const QueryStats& closestStats, const QueryStats& anyStats) {
  const double n = double(rays);
  return std::string("\"") + name + "\": {\"rays\": " + std::to_string(rays) +
         ", \"hit\": " + std::to_string(hit) + ", \"closest_seconds\": " + number(closest) +
         ", \"any_seconds\": " + number(any) + ", \"rays_per_second\": " + number(n / closest) +
         ", \"boxes_per_ray\": " + number(double(closestStats.boxTests) / n) +
         ", \"triangles_per_ray\": " + number(double(closestStats.triangleTests) / n) +
         ", \"any_boxes_per_ray\": " + number(double(anyStats.boxTests) / n) +
         ", \"any_triangles_per_ray\": " + number(double(anyStats.triangleTests) / n);
}

// One batch of rays: facetree's closest and any hits (and Embree's, alternating), their times,
// the boxes and triangles tested a ray, and the hits compared.
std::string rayBatch(const char* name, const std::vector<Ray>& rays, const Tracer& tracer,
                     const EmbreeScene* embree, const Args& a) {
  std::vector<double> closest, any, embreeClosest, embreeAny;
  std::vector<RayHit> hits, peer;
  std::vector<uint8_t> blocked, peerBlocked;
  QueryStats closestStats, anyStats;
  for (unsigned r = 0; r < a.repeat; ++r) {
    closestStats = anyStats = {};
    // Embree's build threads spin a while once idle: the tracer's threads would share the cores.
    if (embree) std::this_thread::sleep_for(std::chrono::milliseconds(300));
    auto start = Clock::now();
    hits = tracer.intersect(rays, a.threads, &closestStats);
    closest.push_back(seconds(start));
    start = Clock::now();
    blocked = tracer.occluded(rays, a.threads, &anyStats);
    any.push_back(seconds(start));
    if (!embree) continue;
    start = Clock::now();
    peer = embree->intersect(rays, a.threads);
    embreeClosest.push_back(seconds(start));
    start = Clock::now();
    peerBlocked = embree->occluded(rays, a.threads);
    embreeAny.push_back(seconds(start));
  }
  const double n = double(rays.size());
  uint64_t hit = 0;
  for (const RayHit& h : hits) hit += h.face != facetree::kNoHit;
  std::string out = rayFields(name, rays.size(), hit, median(closest), median(any), closestStats, anyStats);
  if (embree) {
    // The same triangle, or both missing; t within 1e-5 relative where both hit. Where the two t
    // differ by more, each against the exact t of its own triangle (the plane's, in long double):
    // whose rounding it is.
    uint64_t same = 0, grazing = 0, tOutside = 0, outsideEmbreeFurther = 0, anySame = 0, differentExact = 0,
             outsideFacetreeExact = 0;
    double worstT = 0, worstExact = 0, embreeWorstExact = 0;
    for (size_t k = 0; k < rays.size(); ++k) {
      const RayHit &h = hits[k], &e = peer[k];
      anySame += blocked[k] == peerBlocked[k];
      if (h.face == e.face) ++same;
      // Rays on different triangles (or one missing): whether facetree's is the true nearest of the
      // two, by the exact test of both.
      bool facetreeExact = true;  // on different triangles: facetree's the true nearest of the two
      if (h.face != e.face) {
        const ClusterFile& file = tracer.layout->file();
        const long double inf = std::numeric_limits<long double>::infinity();
        const long double ours = h.face == facetree::kNoHit ? inf : exactHit(file, rays[k], h.face);
        const long double theirs = e.face == facetree::kNoHit ? inf : exactHit(file, rays[k], e.face);
        facetreeExact = h.face == facetree::kNoHit ? theirs == inf : ours < inf && ours <= theirs;
        differentExact += facetreeExact;
      }
      if (h.face != facetree::kNoHit)
        worstExact = std::max(worstExact, relative(h.t, exactT(tracer.layout->file(), rays[k], h.face)));
      if (e.face != facetree::kNoHit)
        embreeWorstExact =
            std::max(embreeWorstExact, relative(e.t, exactT(tracer.layout->file(), rays[k], e.face)));
      if (h.face == facetree::kNoHit || e.face == facetree::kNoHit) continue;
      const double rel = relative(h.t, e.t);
      worstT = std::max(worstT, rel);
      grazing += h.face != e.face && rel <= 1e-6;
      if (rel > 1e-5) {
        ++tOutside;
        const bool embreeFurther = relative(e.t, exactT(tracer.layout->file(), rays[k], e.face)) >
                                   relative(h.t, exactT(tracer.layout->file(), rays[k], h.face));
        outsideEmbreeFurther += embreeFurther;
        // Same triangle: the t nearer the exact one; different triangles: the true nearest hit.
        outsideFacetreeExact += h.face == e.face ? embreeFurther : facetreeExact;
      }
    }
    out += ", \"embree_closest_seconds\": " + number(median(embreeClosest)) +
           ", \"embree_any_seconds\": " + number(median(embreeAny)) +
           ", \"different_triangle_facetree_exact\": " + std::to_string(differentExact) +
           ", \"t_outside_1e-5_facetree_exact\": " + std::to_string(outsideFacetreeExact) +
           ", \"closest_ratio\": " + number(median(closest) / median(embreeClosest)) +
           ", \"any_ratio\": " + number(median(any) / median(embreeAny)) +
           ", \"same_triangle\": " + number(double(same) / n) +
           ", \"different_triangle\": " + std::to_string(rays.size() - same) +
           ", \"different_but_t_within_1e-6\": " + std::to_string(grazing) +
           ", \"t_outside_1e-5\": " + std::to_string(tOutside) +
           ", \"t_outside_1e-5_embree_further_from_exact\": " + std::to_string(outsideEmbreeFurther) +
           ", \"worst_t_relative\": " + number(worstT) +
           ", \"facetree_worst_t_against_exact\": " + number(worstExact) +
           ", \"embree_worst_t_against_exact\": " + number(embreeWorstExact) +
           ", \"same_any\": " + number(double(anySame) / n);
  }
  return out + "}";
}

// Rays through the reader, generated and traced `a.batch` at a time, so the benchmark holds one
// batch's rays and hits beside the reader, not all of them: the process's peak is the reader's.
std::string streamedRays(const char* name, uint64_t count,
                         const std::function<std::vector<Ray>(uint64_t, uint64_t)>& generate,
                         const Tracer& tracer, const Args& a) {
  double closest = 0, any = 0;
  uint64_t hit = 0;
  QueryStats closestStats, anyStats;
  for (uint64_t begin = 0; begin < count; begin += a.batch) {
    const uint64_t end = std::min(count, begin + a.batch);
    const std::vector<Ray> rays = generate(begin, end);
    auto start = Clock::now();
    const std::vector<RayHit> hits = tracer.intersect(rays, a.threads, &closestStats);
    closest += seconds(start);
    start = Clock::now();
    tracer.occluded(rays, a.threads, &anyStats);
    any += seconds(start);
    for (const RayHit& h : hits) hit += h.face != facetree::kNoHit;
  }
  return rayFields(name, count, hit, closest, any, closestStats, anyStats) + "}";
}

// Boxes about random surface points (a tenth of them oriented at random), a hundredth of the
// diagonal across, and nearest points from random points in and about the box.
void save(const std::string& path, const std::vector<float>& values) {
  std::FILE* out = std::fopen(path.c_str(), "wb");
  if (!out) throw std::runtime_error("cannot write " + path);
  const size_t written = std::fwrite(values.data(), sizeof(float), values.size(), out);
  if (std::fclose(out) != 0 || written != values.size()) throw std::runtime_error("cannot write " + path);
}

std::string boxAndNearest(const ClusterFile& f, const Bounds& b, const Args& a) {
  std::mt19937_64 rng(7);
  const size_t triangles = f.indices.size() / 3;
  std::vector<facetree::QueryBox> boxes(a.queries);
  for (facetree::QueryBox& q : boxes) {
    const size_t t = size_t(rng() % std::max<size_t>(triangles, 1));
    const glm::vec3 c = triangles ? (f.vertices[f.indices[3 * t]] + f.vertices[f.indices[3 * t + 1]] +
                                     f.vertices[f.indices[3 * t + 2]]) /
                                        3.0f
                                  : b.centre();
    q.center = c;
    q.halfExtent = glm::vec3(0.005f * b.diagonal()) * (0.5f + glm::vec3(unit(rng), unit(rng), unit(rng)));
    if (rng() % 10 == 0) q.orientation = glm::normalize(glm::quat(unit(rng) - 0.5f, onSphere(rng)));
  }
  std::vector<glm::vec3> points(a.queries);
  const glm::vec3 grow(0.1f * b.diagonal());
  for (glm::vec3& p : points)
    p = b.lo - grow + glm::vec3(unit(rng), unit(rng), unit(rng)) * (b.hi - b.lo + 2.0f * grow);
  if (!a.saveRays
           .empty()) {  // the same queries for Python: boxes as centre, half extents, quaternion x y z w
    std::vector<float> values;
    for (const facetree::QueryBox& q : boxes)
      values.insert(values.end(),
                    {q.center.x, q.center.y, q.center.z, q.halfExtent.x, q.halfExtent.y, q.halfExtent.z,
                     q.orientation.x, q.orientation.y, q.orientation.z, q.orientation.w});
    save(a.saveRays + ".boxes", values);
    values.clear();
    for (const glm::vec3& p : points) values.insert(values.end(), {p.x, p.y, p.z});
    save(a.saveRays + ".points", values);
  }
  // The same boxes along the world axes, for Python's overlap(lo, hi) on their centre -+ half extent.
  std::vector<facetree::QueryBox> aligned(boxes);
  for (facetree::QueryBox& q : aligned) q.orientation = glm::quat(1.0f, 0.0f, 0.0f, 0.0f);
  const facetree::QueryOptions o{a.threads};
  std::vector<double> boxTimes, alignedTimes, nearTimes;
  QueryStats boxStats, nearStats;
  uint64_t found = 0;
  for (unsigned r = 0; r < a.repeat; ++r) {
    boxStats = nearStats = {};
    auto start = Clock::now();
    const auto hits = facetree::overlap(f, boxes, o, &boxStats);
    boxTimes.push_back(seconds(start));
    found = 0;
    for (const auto& h : hits) found += h.size();
    start = Clock::now();
    facetree::overlap(f, aligned, o);
    alignedTimes.push_back(seconds(start));
    start = Clock::now();
    facetree::nearest(f, points, std::numeric_limits<float>::infinity(), o, &nearStats);
    nearTimes.push_back(seconds(start));
  }
  const double n = double(a.queries);
  return "\"boxes\": {\"queries\": " + std::to_string(a.queries) +
         ", \"queries_per_second\": " + number(n / median(boxTimes)) +
         ", \"boxes_per_query\": " + number(double(boxStats.boxTests) / n) +
         ", \"triangles_per_query\": " + number(double(boxStats.triangleTests) / n) +
         ", \"found_per_query\": " + number(double(found) / n) +
         "}, \"aligned\": {\"queries\": " + std::to_string(a.queries) +
         ", \"queries_per_second\": " + number(n / median(alignedTimes)) +
         "}, \"nearest\": {\"queries\": " + std::to_string(a.queries) +
         ", \"queries_per_second\": " + number(n / median(nearTimes)) +
         ", \"boxes_per_query\": " + number(double(nearStats.boxTests) / n) +
         ", \"triangles_per_query\": " + number(double(nearStats.triangleTests) / n) + "}";
}

}  // namespace

int main(int argc, char** argv) try {
  const Args a = parse(argc, argv);
  std::string json = "{\"file\": \"" + a.file + "\", \"threads\": " + std::to_string(a.threads) +
                     ", \"prefix\": " + number(a.prefix);
  if (a.readerMemory) {
    // Through the lazy reader, under its cap: the rays frame the root's oriented box (a pass
    // over the vertices would read the whole file).
    facetree::ClusterFileReader reader(a.file, facetree::ReaderOptions{a.readerMemory, {}});
    Bounds b;
    const facetree::NodeBox box = reader.node(0).box;
    const glm::mat3 axes = glm::mat3_cast(box.orientation);
    b.lo = b.hi = box.center;
    for (int corner = 0; corner < 8; ++corner) {
      glm::vec3 p = box.center;
      for (int k = 0; k < 3; ++k) p += axes[k] * (corner >> k & 1 ? box.halfExtent[k] : -box.halfExtent[k]);
      b.lo = glm::min(b.lo, p);
      b.hi = glm::max(b.hi, p);
    }
    const auto indexStart = Clock::now();
    facetree::ReaderQueryIndex index(reader);
    const double indexSeconds = seconds(indexStart);
    const Tracer tracer{nullptr, &index};
    json += ", \"reader_memory\": " + std::to_string(a.readerMemory) +
            ", \"index_seconds\": " + number(indexSeconds) +
            ", \"index_temporary_bytes\": " + std::to_string(index.temporaryBytes()) +
            // What the benchmark itself holds beside the reader: one batch's rays, closest hits and
            // any hits.
            ", \"batch\": " + std::to_string(a.batch) +
            ", \"rays_bytes\": " + std::to_string(a.batch * (sizeof(Ray) + sizeof(RayHit) + 1)) + ", ";
    std::mt19937_64 rng(1);
    if (!a.loadRays.empty()) {  // the rays another run saved, read a batch at a time
      for (const char* kind : {"camera", "random"}) {
        const std::string path = a.loadRays + "." + kind;
        std::FILE* in = std::fopen(path.c_str(), "rb");
        if (!in) throw std::runtime_error("cannot read " + path);
        std::fseek(in, 0, SEEK_END);
        const auto count = static_cast<uint64_t>(std::ftell(in)) / (6 * sizeof(float));
        json += streamedRays(
                    kind, count,
                    [&](uint64_t begin, uint64_t end) {
                      std::vector<float> v(6 * (end - begin));
                      std::fseek(in, static_cast<long>(begin * 6 * sizeof(float)), SEEK_SET);
                      if (std::fread(v.data(), sizeof(float), v.size(), in) != v.size())
                        throw std::runtime_error("cannot read " + path);
                      std::vector<Ray> rays(end - begin);
                      for (size_t k = 0; k < rays.size(); ++k) {
                        rays[k].origin = {v[6 * k], v[6 * k + 1], v[6 * k + 2]};
                        rays[k].direction = {v[6 * k + 3], v[6 * k + 4], v[6 * k + 5]};
                      }
                      return rays;
                    },
                    tracer, a) +
                (kind[0] == 'c' ? ", " : "");
        std::fclose(in);
      }
      std::printf("%s}\n", json.c_str());
      return 0;
    }
    json += streamedRays(
                "camera", cameraRayCount(a.rays),
                [&](uint64_t begin, uint64_t end) { return cameraRays(b, a.rays, begin, end); }, tracer, a) +
            ", " +
            streamedRays(
                "random", a.rays,
                [&](uint64_t begin, uint64_t end) { return randomRays(b, end - begin, rng); }, tracer, a);
    std::printf("%s}\n", json.c_str());
    return 0;
  }
  const auto loadStart = Clock::now();
  ClusterFile f = facetree::readClusterFile(a.file);
  const double loadSeconds = seconds(loadStart);
  const size_t nodes = f.nodes.size();
  f.nodes.resize(std::clamp<size_t>(size_t(std::llround(a.prefix * double(nodes))), 1, nodes));
  const Bounds b = bounds(f.vertices);
  json += ", \"triangles\": " + std::to_string(f.indices.size() / 3) +
          ", \"nodes\": " + std::to_string(f.nodes.size()) +
          ", \"branching\": " + std::to_string(f.header.branching) +
          ", \"load_seconds\": " + number(loadSeconds);
  std::unique_ptr<EmbreeScene> embree;
  if (a.embree) {
    embree = std::make_unique<EmbreeScene>(f, a.threads);
    json += ", \"embree_build_seconds\": " + number(embree->buildSeconds);
  }
  const auto layoutStart = Clock::now();
  const facetree::RayLayout layout(f);
  json += ", \"layout_seconds\": " + number(seconds(layoutStart));
  const Tracer tracer{&layout, nullptr};
  const std::vector<Ray> camera = cameraRays(b, a.rays), random = randomRays(b, a.rays, 1);
  if (!a.saveRays.empty())
    for (const auto& [name, rays] : {std::pair{".camera", &camera}, std::pair{".random", &random}}) {
      std::vector<float> values;
      for (const Ray& r : *rays)
        values.insert(values.end(),
                      {r.origin.x, r.origin.y, r.origin.z, r.direction.x, r.direction.y, r.direction.z});
      save(a.saveRays + name, values);
    }
  json += ", " + rayBatch("camera", camera, tracer, embree.get(), a) + ", " +
          rayBatch("random", random, tracer, embree.get(), a);
  if (!a.raysOnly) json += ", " + boxAndNearest(f, b, a);
  std::printf("%s}\n", json.c_str());
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "query_bench: %s\n", e.what());
  return 1;
}
