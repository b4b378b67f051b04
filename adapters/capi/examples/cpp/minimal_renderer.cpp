// A minimal renderer loop guided through Lodestar's C++ wrapper (lodestar.hpp over the C
// API): a Cornell-style room with a
// ceiling light and a block, intersected by brute force, rendered with BSDF sampling
// alone and then with a guide that learns along every path (Dahm & Keller's Eq. 1, the
// targets computed by the library's path recorder from what the loop records), over two
// threads. The guide is saved to a byte buffer, released, reloaded, checked to
// sample exactly as before, and used once more. Prints the image means with their
// standard errors and exits non-zero when they disagree or any call fails.
//
// Build: g++ -std=c++17 -O2 minimal_renderer.cpp $(pkg-config --cflags --libs lodestar) -pthread
//        (scripts/install-capi.sh PREFIX installs the library, the headers and lodestar.pc)
// Run:   ./minimal_renderer [passes]   (default 16)
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <thread>
#include <vector>

#include "lodestar.hpp"

namespace {

struct Vec3 {
    float x, y, z;
};
Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 operator*(Vec3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
float dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec3 cross(Vec3 a, Vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
Vec3 normalize(Vec3 a) { return a * (1.0f / std::sqrt(dot(a, a))); }
LodestarVec3 to_c(Vec3 a) { return {a.x, a.y, a.z}; }
Vec3 from_c(LodestarVec3 a) { return {a.x, a.y, a.z}; }

constexpr float kPi = 3.14159265358979f;
constexpr float kAlbedo = 0.7f;
constexpr float kLightRadiance = 12.0f;

using lodestar::check;  // throws lodestar::Error (status and message) on a failed call

// PCG32 (O'Neill): a small, fast generator with independent streams per thread.
struct Random {
    uint64_t state, increment;
    Random(uint64_t seed, uint64_t stream) : state(0), increment((stream << 1u) | 1u) {
        next();
        state += seed;
        next();
    }
    uint32_t next() {
        uint64_t old = state;
        state = old * 6364136223846793005ULL + increment;
        uint32_t shifted = uint32_t(((old >> 18u) ^ old) >> 27u);
        uint32_t rotation = uint32_t(old >> 59u);
        return (shifted >> rotation) | (shifted << ((32 - rotation) & 31));
    }
    float uniform() { return float(next() >> 8) * (1.0f / 16777216.0f); }  // in [0, 1)
};

struct Triangle {
    Vec3 a, b, c, normal;
    bool emitter;
};

struct Scene {
    std::vector<Triangle> triangles;

    // A quad p0 p1 p2 p3 (in order around its edge) whose front faces `facing`.
    void add_quad(Vec3 p0, Vec3 p1, Vec3 p2, Vec3 p3, Vec3 facing, bool emitter = false) {
        if (dot(cross(p1 - p0, p2 - p0), facing) < 0) std::swap(p1, p3);
        Vec3 n = normalize(cross(p1 - p0, p2 - p0));
        triangles.push_back({p0, p1, p2, n, emitter});
        triangles.push_back({p0, p2, p3, n, emitter});
    }

    // Möller–Trumbore over every triangle: the nearest hit in (1e-4, t_max).
    bool intersect(Vec3 origin, Vec3 direction, float& t_hit, int& index) const {
        t_hit = 1e30f;
        index = -1;
        for (size_t i = 0; i < triangles.size(); ++i) {
            const Triangle& tri = triangles[i];
            Vec3 e1 = tri.b - tri.a, e2 = tri.c - tri.a;
            Vec3 p = cross(direction, e2);
            float det = dot(e1, p);
            if (std::fabs(det) < 1e-12f) continue;
            float inv = 1.0f / det;
            Vec3 s = origin - tri.a;
            float u = dot(s, p) * inv;
            if (u < 0 || u > 1) continue;
            Vec3 q = cross(s, e1);
            float v = dot(direction, q) * inv;
            if (v < 0 || u + v > 1) continue;
            float t = dot(e2, q) * inv;
            if (t > 1e-4f && t < t_hit) {
                t_hit = t;
                index = int(i);
            }
        }
        return index >= 0;
    }
};

// The unit room [0,1]³ open towards the camera (z = 0), a ceiling light and a block.
Scene build_scene() {
    Scene s;
    auto P = [](float x, float y, float z) { return Vec3{x, y, z}; };
    s.add_quad(P(0, 0, 0), P(1, 0, 0), P(1, 0, 1), P(0, 0, 1), P(0, 1, 0));     // floor
    s.add_quad(P(0, 1, 0), P(1, 1, 0), P(1, 1, 1), P(0, 1, 1), P(0, -1, 0));    // ceiling
    s.add_quad(P(0, 0, 1), P(1, 0, 1), P(1, 1, 1), P(0, 1, 1), P(0, 0, -1));    // back
    s.add_quad(P(0, 0, 0), P(0, 0, 1), P(0, 1, 1), P(0, 1, 0), P(1, 0, 0));     // left
    s.add_quad(P(1, 0, 0), P(1, 0, 1), P(1, 1, 1), P(1, 1, 0), P(-1, 0, 0));    // right
    const float x0 = 0.55f, x1 = 0.8f, z0 = 0.45f, z1 = 0.7f, h = 0.6f;        // block
    s.add_quad(P(x0, h, z0), P(x1, h, z0), P(x1, h, z1), P(x0, h, z1), P(0, 1, 0));
    s.add_quad(P(x0, 0, z0), P(x1, 0, z0), P(x1, h, z0), P(x0, h, z0), P(0, 0, -1));
    s.add_quad(P(x0, 0, z1), P(x1, 0, z1), P(x1, h, z1), P(x0, h, z1), P(0, 0, 1));
    s.add_quad(P(x0, 0, z0), P(x0, 0, z1), P(x0, h, z1), P(x0, h, z0), P(-1, 0, 0));
    s.add_quad(P(x1, 0, z0), P(x1, 0, z1), P(x1, h, z1), P(x1, h, z0), P(1, 0, 0));
    s.add_quad(P(0.4f, 0.999f, 0.4f), P(0.6f, 0.999f, 0.4f), P(0.6f, 0.999f, 0.6f), P(0.4f, 0.999f, 0.6f),
               P(0, -1, 0), true);                                               // light
    return s;
}

// Probes go on every surface but the light, which reflects nothing.
lodestar::Guide create_guide(const Scene& scene) {
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    for (const Triangle& tri : scene.triangles) {
        if (tri.emitter) continue;
        for (Vec3 p : {tri.a, tri.b, tri.c}) {
            indices.push_back(uint32_t(positions.size() / 3));
            positions.insert(positions.end(), {p.x, p.y, p.z});
        }
    }
    LodestarGuideConfig config;
    check(lodestar_guide_config_default(&config), "lodestar_guide_config_default");
    config.budget_bytes = 256 * 1024;
    return lodestar::Guide::create(config, positions, indices);
}

Vec3 cosine_sample(Vec3 n, float u0, float u1) {
    Vec3 t = std::fabs(n.x) > 0.5f ? normalize(cross(n, Vec3{0, 1, 0})) : normalize(cross(n, Vec3{1, 0, 0}));
    Vec3 b = cross(n, t);
    float r = std::sqrt(u0), phi = 2 * kPi * u1;
    return normalize(t * (r * std::cos(phi)) + b * (r * std::sin(phi)) + n * std::sqrt(std::fmax(0.0f, 1 - u0)));
}

struct Sums {
    double sum = 0, sum_squares = 0;
    uint64_t count = 0;
    void add(double v) {
        sum += v;
        sum_squares += v * v;
        ++count;
    }
    double mean() const { return sum / double(count); }
    double standard_error() const {
        double m = mean();
        return std::sqrt(std::fmax(0.0, sum_squares / double(count) - m * m) / double(count));
    }
};

constexpr int kWidth = 48, kHeight = 36, kMaxDepth = 12;
constexpr float kGuideProbability = 0.5f;

// One path through pixel (px, py): recorded into `recorder` for `guide` to learn from
// (Eq. 1's targets come from the recorder), sampling the guide when `guided`.
float trace_path(const Scene& scene, const lodestar::Guide* guide, lodestar::PathRecorder& recorder, bool guided,
                 int px, int py, Random& rng) {
    const float tan_half_fov = std::tan(0.5f * 40.0f * kPi / 180.0f);
    float sx = (2 * (px + rng.uniform()) / kWidth - 1) * tan_half_fov * kWidth / kHeight;
    float sy = (1 - 2 * (py + rng.uniform()) / kHeight) * tan_half_fov;
    Vec3 origin{0.5f, 0.5f, -1.4f}, direction = normalize(Vec3{sx, sy, 1});
    float throughput = 1, radiance = 0;
    if (guide) check(recorder.clear(), "clear");
    for (int depth = 0; depth < kMaxDepth; ++depth) {
        float t;
        int index;
        bool hit = scene.intersect(origin, direction, t, index);
        if (guide && hit) check(recorder.reached(t), "reached");
        float emitted = 0;
        if (hit && scene.triangles[index].emitter)
            emitted = dot(direction, scene.triangles[index].normal) < 0 ? kLightRadiance : 0;
        if (!hit || scene.triangles[index].emitter) {
            radiance += throughput * emitted;
            if (guide) check(recorder.arrive(emitted), "arrive");
            break;
        }
        Vec3 x = origin + direction * t, n = scene.triangles[index].normal;
        if (dot(n, direction) > 0) n = n * -1.0f;
        lodestar::Region region{LODESTAR_NO_REGION, 0, to_c(n)};
        if (guide) region = guide->locate(to_c(x), to_c(n));
        // Eq. (1): beyond this vertex, the previous one learns this one's reflected Q.
        if (guide && region.index != LODESTAR_NO_REGION) {
            float reflected = guide->estimate_integral_lambertian(region, to_c(n), kAlbedo, 0.5f, 0.5f);
            check(recorder.estimate(reflected), "estimate");
        }
        bool use_guide = guided && region.index != LODESTAR_NO_REGION;
        float u0 = rng.uniform(), u1 = rng.uniform();
        Vec3 wi;
        if (use_guide && rng.uniform() < kGuideProbability) {
            wi = from_c(guide->sample(region, u0, u1).direction);
        } else {
            wi = cosine_sample(n, u0, u1);
        }
        float cos_theta = dot(wi, n);
        if (cos_theta <= 0) break;  // below the surface: the BSDF is zero there
        float pdf = cos_theta / kPi;
        if (use_guide) {
            float guide_pdf = 0;
            check(guide->pdf(region, to_c(wi), guide_pdf), "pdf");  // the status form, for once
            pdf = kGuideProbability * guide_pdf + (1 - kGuideProbability) * pdf;  // one-sample MIS
        }
        float factor = kAlbedo / kPi * cos_theta / pdf;
        throughput *= factor;
        if (depth >= 3) {  // Russian roulette
            float survive = std::fmin(throughput, 0.95f);
            if (rng.uniform() >= survive) break;
            throughput /= survive;
            factor /= survive;
        }
        if (guide) {
            // Without an estimate of its own this vertex hands its target back, scaled.
            if (region.index == LODESTAR_NO_REGION) check(recorder.carry(factor), "carry");
            check(recorder.scattered(region, to_c(x), to_c(wi), pdf, throughput), "scattered");
        }
        origin = x;
        direction = wi;
    }
    if (guide) recorder.learn(*guide);
    return radiance;
}

// `passes` passes of one path per pixel over two threads; the guide (if any) learns in
// every pass and rebuilds its sampling distributions between them.
Sums render(const Scene& scene, lodestar::Guide* guide, bool guided, int passes, uint64_t seed) {
    constexpr int kThreads = 2;
    Sums total;
    for (int pass = 0; pass < passes; ++pass) {
        Sums per_thread[kThreads];
        std::vector<std::thread> workers;
        for (int w = 0; w < kThreads; ++w) {
            workers.emplace_back([&, w] {
                Random rng(seed * 1000003u + pass, uint64_t(w));
                lodestar::PathRecorder recorder;  // one per thread; released when it goes
                check(lodestar::PathRecorder::create(recorder), "path_recorder_create");
                try {
                    for (int py = w; py < kHeight; py += kThreads)
                        for (int px = 0; px < kWidth; ++px)
                            per_thread[w].add(trace_path(scene, guide, recorder, guided, px, py, rng));
                } catch (const lodestar::Error& e) {
                    std::fprintf(stderr, "%s\n", e.what());
                    std::exit(1);
                }
            });
        }
        for (std::thread& worker : workers) worker.join();
        for (const Sums& s : per_thread) {
            total.sum += s.sum;
            total.sum_squares += s.sum_squares;
            total.count += s.count;
        }
        if (guide) check(guide->rebuild(), "rebuild");
    }
    return total;
}

bool agree(const Sums& a, const Sums& b) {
    double error = std::sqrt(a.standard_error() * a.standard_error() + b.standard_error() * b.standard_error());
    return std::fabs(a.mean() - b.mean()) <= 4 * error;
}

}  // namespace

int run(int argc, char** argv) {
    if (lodestar_version() != LODESTAR_VERSION) {
        std::fprintf(stderr, "header version %u, library version %u\n", LODESTAR_VERSION, lodestar_version());
        return 1;
    }
    const Scene scene = build_scene();
    // Passes per render (one path per pixel each); fewer under valgrind.
    const int passes = argc > 1 ? std::atoi(argv[1]) : 16;
    if (passes < 2) {
        std::fprintf(stderr, "usage: %s [passes >= 2]\n", argv[0]);
        return 2;
    }
    Sums unguided = render(scene, nullptr, false, passes, 1);
    std::printf("unguided mean %.5f +- %.5f\n", unguided.mean(), unguided.standard_error());

    lodestar::Guide guide = create_guide(scene);
    Sums guided = render(scene, &guide, true, passes, 2);
    std::printf("guided mean %.5f +- %.5f\n", guided.mean(), guided.standard_error());
    const LodestarGuideStats stats = guide.stats();
    std::printf("guide regions %llu, accepted updates %llu, bytes %llu\n", (unsigned long long)stats.regions,
                (unsigned long long)stats.accepted_updates, (unsigned long long)stats.memory_bytes);

    // Save, release, reload: the reloaded guide must sample exactly as the saved one.
    const std::vector<uint8_t> buffer = guide.save();
    std::vector<LodestarDirectionSample> before;
    for (uint32_t r = 0; r < stats.regions; r += 7)
        for (int i = 0; i < 4; ++i) before.push_back(guide.sample(lodestar::Region{r, 0, {0, 0, 1}}, 0.1f + 0.2f * i, 0.3f));
    guide.reset();
    guide = lodestar::Guide::load(buffer);
    check(guide.validate(), "validate");
    size_t mismatches = 0, k = 0;
    for (uint32_t r = 0; r < stats.regions; r += 7)
        for (int i = 0; i < 4; ++i, ++k) {
            const LodestarDirectionSample sample = guide.sample(lodestar::Region{r, 0, {0, 0, 1}}, 0.1f + 0.2f * i, 0.3f);
            const LodestarDirectionSample& old = before[k];
            if (sample.pdf != old.pdf || sample.direction.x != old.direction.x ||
                sample.direction.y != old.direction.y || sample.direction.z != old.direction.z)
                ++mismatches;
        }
    std::printf("saved %zu bytes; reloaded guide: %zu of %zu samples differ\n", buffer.size(), mismatches,
                before.size());
    Sums reloaded = render(scene, &guide, true, passes / 2, 3);
    std::printf("reloaded mean %.5f +- %.5f\n", reloaded.mean(), reloaded.standard_error());

    bool ok = mismatches == 0 && agree(unguided, guided) && agree(unguided, reloaded) && unguided.mean() > 0;
    std::printf("%s\n", ok ? "means agree" : "MEANS DISAGREE");
    return ok ? 0 : 1;
}

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const lodestar::Error& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return 1;
    }
}
