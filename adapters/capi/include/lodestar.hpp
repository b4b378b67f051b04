/* Lodestar's C++ wrapper: owning, move-only handles over the C API of lodestar.h.
 * Header-only (C++17). Written by hand beside the generated lodestar.h.
 *
 * Every call comes in two forms, by choice:
 *   - status returns: `LodestarStatus locate(p, n, Region& out) const noexcept` (outputs
 *     by reference, nothing thrown; `lodestar::last_error()` says what was wrong);
 *   - exceptions: `Region locate(p, n) const` throws `lodestar::Error` (status and
 *     message) on failure. Left out when exceptions are off (-fno-exceptions).
 *
 * Handles release what they own in their destructors; `get()` hands the C pointer to
 * code that calls the C API directly. Thread rules are the C API's (lodestar.h). */
#ifndef LODESTAR_HPP
#define LODESTAR_HPP

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "lodestar.h"

#if defined(__cpp_exceptions) || defined(__EXCEPTIONS)
#define LODESTAR_HPP_EXCEPTIONS 1
#include <stdexcept>
#endif

namespace lodestar {

using Status = LodestarStatus;
using Vec3 = LodestarVec3;
using Region = LodestarRegion;
using DirectionSample = LodestarDirectionSample;
using EnvSample = LodestarEnvSample;

/// This thread's message for the last failed call.
inline std::string last_error() { return lodestar_last_error(); }

#ifdef LODESTAR_HPP_EXCEPTIONS
/// A failed call: its status and the library's message naming what was wrong.
class Error : public std::runtime_error {
public:
    Error(Status status, const std::string& call)
        : std::runtime_error(call + ": " + lodestar_status_name(status) + ": " + last_error()), status_(status) {}
    Status status() const noexcept { return status_; }

private:
    Status status_;
};

/// Throws `Error` unless `status` is OK.
inline void check(Status status, const char* call) {
    if (status != LODESTAR_STATUS_OK) throw Error(status, call);
}
#endif

namespace detail {
/// A move-only owner of a C handle freed by `Release`.
template <typename T, Status (*Release)(T*)>
class Handle {
public:
    Handle() noexcept = default;
    explicit Handle(T* handle) noexcept : handle_(handle) {}
    Handle(Handle&& other) noexcept : handle_(std::exchange(other.handle_, nullptr)) {}
    Handle& operator=(Handle&& other) noexcept {
        if (this != &other) {
            reset();
            handle_ = std::exchange(other.handle_, nullptr);
        }
        return *this;
    }
    Handle(const Handle&) = delete;
    Handle& operator=(const Handle&) = delete;
    ~Handle() { reset(); }

    T* get() const noexcept { return handle_; }
    explicit operator bool() const noexcept { return handle_ != nullptr; }
    /// Releases the handle now (what the destructor does).
    void reset() noexcept {
        if (handle_) (void)Release(std::exchange(handle_, nullptr));
    }

protected:
    /// For the static create/load calls: adopt what a C call wrote to `out`.
    T** out() noexcept {
        reset();
        return &handle_;
    }

private:
    T* handle_ = nullptr;
};

/// `save` of any guide kind into a vector: asks for the size, then writes.
template <typename T>
Status save(const T* handle, Status (*save)(const T*, uint8_t*, size_t, size_t*),
            Status (*size_of)(const T*, size_t*), std::vector<uint8_t>& out) noexcept {
    size_t size = 0;
    Status s = size_of(handle, &size);
    if (s != LODESTAR_STATUS_OK) return s;
    out.resize(size);
    s = save(handle, out.data(), out.size(), &size);
    out.resize(s == LODESTAR_STATUS_OK ? size : 0);
    return s;
}
}  // namespace detail

/// A directional guide of any structure (lodestar_guide_*).
class Guide : public detail::Handle<LodestarGuide, lodestar_guide_release> {
public:
    using Handle::Handle;

    /// A hemisphere grid over a triangle mesh (3 floats per vertex, 3 indices per triangle).
    static Status create(const LodestarGuideConfig& config, const std::vector<float>& positions,
                         const std::vector<uint32_t>& indices, Guide& out) noexcept {
        return lodestar_guide_create(&config, positions.data(), positions.size() / 3, indices.data(),
                                     indices.size() / 3, out.out());
    }
    static Status create_volume(const LodestarVolumeConfig& config, Vec3 low, Vec3 high, Guide& out) noexcept {
        return lodestar_guide_create_volume(&config, low, high, out.out());
    }
    static Status create_mixture(const LodestarMixtureConfig& config, Vec3 low, Vec3 high, Guide& out) noexcept {
        return lodestar_guide_create_mixture(&config, low, high, out.out());
    }
    static Status create_tree(const LodestarTreeConfig& config, Vec3 low, Vec3 high, Guide& out) noexcept {
        return lodestar_guide_create_tree(&config, low, high, out.out());
    }
    /// Any structure saved by `save`.
    static Status load(const std::vector<uint8_t>& bytes, Guide& out) noexcept {
        return lodestar_guide_load(bytes.data(), bytes.size(), out.out());
    }

    Status locate(Vec3 position, Vec3 normal, Region& out) const noexcept {
        return lodestar_guide_locate(get(), position, normal, &out);
    }
    Status sample(Region region, float u0, float u1, DirectionSample& out) const noexcept {
        return lodestar_guide_sample(get(), region, u0, u1, &out);
    }
    Status pdf(Region region, Vec3 direction, float& out) const noexcept {
        return lodestar_guide_pdf(get(), region, direction, &out);
    }
    Status update_sampled(Region region, Vec3 direction, float target, float pdf,
                          LodestarUpdateOutcome& out) const noexcept {
        return lodestar_guide_update_sampled(get(), region, direction, target, pdf, &out);
    }
    Status estimate_integral_lambertian(Region region, Vec3 normal, float albedo, float u0, float u1,
                                        float& out) const noexcept {
        return lodestar_guide_estimate_integral_lambertian(get(), region, normal, albedo, u0, u1, &out);
    }
    Status structure(uint32_t& out) const noexcept { return lodestar_guide_structure(get(), &out); }
    Status stats(LodestarGuideStats& out) const noexcept { return lodestar_guide_stats(get(), &out); }
    Status validate() const noexcept { return lodestar_guide_validate(get()); }
    /// Between passes, with no other call on this guide in flight.
    Status rebuild() noexcept { return lodestar_guide_rebuild(get()); }
    /// Forgets everything learned (as created); regions located before are stale.
    Status reset() noexcept { return lodestar_guide_reset(get()); }
    /// Adds what `other` learned (hemisphere grids of the same scene and config).
    Status merge(const Guide& other) noexcept { return lodestar_guide_merge(get(), other.get()); }
    Status save(std::vector<uint8_t>& out) const noexcept {
        return detail::save(get(), lodestar_guide_save, lodestar_guide_serialized_size, out);
    }

#ifdef LODESTAR_HPP_EXCEPTIONS
    static Guide create(const LodestarGuideConfig& config, const std::vector<float>& positions,
                        const std::vector<uint32_t>& indices) {
        Guide g;
        check(create(config, positions, indices, g), "lodestar_guide_create");
        return g;
    }
    static Guide create_volume(const LodestarVolumeConfig& config, Vec3 low, Vec3 high) {
        Guide g;
        check(create_volume(config, low, high, g), "lodestar_guide_create_volume");
        return g;
    }
    static Guide create_mixture(const LodestarMixtureConfig& config, Vec3 low, Vec3 high) {
        Guide g;
        check(create_mixture(config, low, high, g), "lodestar_guide_create_mixture");
        return g;
    }
    static Guide create_tree(const LodestarTreeConfig& config, Vec3 low, Vec3 high) {
        Guide g;
        check(create_tree(config, low, high, g), "lodestar_guide_create_tree");
        return g;
    }
    static Guide load(const std::vector<uint8_t>& bytes) {
        Guide g;
        check(load(bytes, g), "lodestar_guide_load");
        return g;
    }
    Region locate(Vec3 position, Vec3 normal) const {
        Region r{};
        check(locate(position, normal, r), "lodestar_guide_locate");
        return r;
    }
    DirectionSample sample(Region region, float u0, float u1) const {
        DirectionSample s{};
        check(sample(region, u0, u1, s), "lodestar_guide_sample");
        return s;
    }
    float pdf(Region region, Vec3 direction) const {
        float p = 0;
        check(pdf(region, direction, p), "lodestar_guide_pdf");
        return p;
    }
    LodestarUpdateOutcome update_sampled(Region region, Vec3 direction, float target, float pdf) const {
        LodestarUpdateOutcome o{};
        check(update_sampled(region, direction, target, pdf, o), "lodestar_guide_update_sampled");
        return o;
    }
    float estimate_integral_lambertian(Region region, Vec3 normal, float albedo, float u0, float u1) const {
        float v = 0;
        check(estimate_integral_lambertian(region, normal, albedo, u0, u1, v),
              "lodestar_guide_estimate_integral_lambertian");
        return v;
    }
    LodestarStructure structure() const {
        uint32_t s = 0;
        check(structure(s), "lodestar_guide_structure");
        return LodestarStructure(s);
    }
    LodestarGuideStats stats() const {
        LodestarGuideStats s{};
        check(stats(s), "lodestar_guide_stats");
        return s;
    }
    std::vector<uint8_t> save() const {
        std::vector<uint8_t> bytes;
        check(save(bytes), "lodestar_guide_save");
        return bytes;
    }
#endif
};

/// One thread's path recorder: Eq. (1)'s targets from the vertices a path records.
class PathRecorder : public detail::Handle<LodestarPathRecorder, lodestar_path_recorder_release> {
public:
    using Handle::Handle;

    static Status create(PathRecorder& out) noexcept { return lodestar_path_recorder_create(out.out()); }
    Status clear() noexcept { return lodestar_path_recorder_clear(get()); }
    Status scattered(Region region, Vec3 origin, Vec3 direction, float pdf, float throughput) noexcept {
        return lodestar_path_recorder_scattered(get(), region, origin, direction, pdf, throughput);
    }
    Status reached(float distance) noexcept { return lodestar_path_recorder_reached(get(), distance); }
    Status arrive(float radiance) noexcept { return lodestar_path_recorder_arrive(get(), radiance); }
    Status estimate(float integral) noexcept { return lodestar_path_recorder_estimate(get(), integral); }
    Status carry(float factor) noexcept { return lodestar_path_recorder_carry(get(), factor); }
    Status learn(const Guide& guide, size_t& accepted) const noexcept {
        return lodestar_path_recorder_learn(get(), guide.get(), &accepted);
    }

#ifdef LODESTAR_HPP_EXCEPTIONS
    static PathRecorder create() {
        PathRecorder r;
        check(create(r), "lodestar_path_recorder_create");
        return r;
    }
    size_t learn(const Guide& guide) const {
        size_t accepted = 0;
        check(learn(guide, accepted), "lodestar_path_recorder_learn");
        return accepted;
    }
#endif
};

/// Learned light selection for next-event estimation (lodestar_light_guide_*).
class LightGuide : public detail::Handle<LodestarLightGuide, lodestar_light_guide_release> {
public:
    using Handle::Handle;

    static Status create(const LodestarLightGuideConfig& config, Vec3 low, Vec3 high, const std::vector<float>& powers,
                         LightGuide& out) noexcept {
        return lodestar_light_guide_create(&config, low, high, powers.data(), powers.size(), out.out());
    }
    static Status load(const std::vector<uint8_t>& bytes, LightGuide& out) noexcept {
        return lodestar_light_guide_load(bytes.data(), bytes.size(), out.out());
    }
    Status cell(Vec3 position, uint32_t& out) const noexcept { return lodestar_light_guide_cell(get(), position, &out); }
    Status select(uint32_t cell, float u, uint32_t& light, float& probability) const noexcept {
        return lodestar_light_guide_select(get(), cell, u, &light, &probability);
    }
    Status probability(uint32_t cell, uint32_t light, float& out) const noexcept {
        return lodestar_light_guide_probability(get(), cell, light, &out);
    }
    Status update(uint32_t cell, uint32_t light, float contribution, bool unoccluded,
                  LodestarUpdateOutcome& out) const noexcept {
        return lodestar_light_guide_update(get(), cell, light, contribution, unoccluded ? 1u : 0u, &out);
    }
    Status rebuild() noexcept { return lodestar_light_guide_rebuild(get()); }
    Status reset() noexcept { return lodestar_light_guide_reset(get()); }
    Status merge(const LightGuide& other) noexcept { return lodestar_light_guide_merge(get(), other.get()); }
    Status save(std::vector<uint8_t>& out) const noexcept {
        size_t size = 0;
        Status s = lodestar_light_guide_save(get(), nullptr, 0, &size);
        if (s != LODESTAR_STATUS_OK) return s;
        out.resize(size);
        return lodestar_light_guide_save(get(), out.data(), out.size(), &size);
    }

#ifdef LODESTAR_HPP_EXCEPTIONS
    static LightGuide create(const LodestarLightGuideConfig& config, Vec3 low, Vec3 high,
                             const std::vector<float>& powers) {
        LightGuide g;
        check(create(config, low, high, powers, g), "lodestar_light_guide_create");
        return g;
    }
    uint32_t cell(Vec3 position) const {
        uint32_t c = 0;
        check(cell(position, c), "lodestar_light_guide_cell");
        return c;
    }
    float probability(uint32_t cell, uint32_t light) const {
        float p = 0;
        check(probability(cell, light, p), "lodestar_light_guide_probability");
        return p;
    }
#endif
};

/// Learned environment sampling for next-event estimation (lodestar_env_guide_*).
class EnvGuide : public detail::Handle<LodestarEnvGuide, lodestar_env_guide_release> {
public:
    using Handle::Handle;

    /// `luminance`: width × height texels, row by row from the top; `sun` may be NULL.
    static Status create(const LodestarEnvGuideConfig& config, Vec3 low, Vec3 high, const float* luminance,
                         size_t width, size_t height, const LodestarSunDisk* sun, EnvGuide& out) noexcept {
        return lodestar_env_guide_create(&config, low, high, luminance, width, height, sun, out.out());
    }
    Status cell(Vec3 position, uint32_t& out) const noexcept { return lodestar_env_guide_cell(get(), position, &out); }
    Status sample(uint32_t cell, float u_lobe, float u0, float u1, EnvSample& out) const noexcept {
        return lodestar_env_guide_sample(get(), cell, u_lobe, u0, u1, &out);
    }
    Status pdf(uint32_t cell, Vec3 direction, float& out) const noexcept {
        return lodestar_env_guide_pdf(get(), cell, direction, &out);
    }
    Status update(uint32_t cell, const EnvSample& sample, float integrand, LodestarUpdateOutcome& out) const noexcept {
        return lodestar_env_guide_update(get(), cell, &sample, integrand, &out);
    }
    Status rebuild() noexcept { return lodestar_env_guide_rebuild(get()); }
    Status reset() noexcept { return lodestar_env_guide_reset(get()); }
    Status merge(const EnvGuide& other) noexcept { return lodestar_env_guide_merge(get(), other.get()); }

#ifdef LODESTAR_HPP_EXCEPTIONS
    static EnvGuide create(const LodestarEnvGuideConfig& config, Vec3 low, Vec3 high, const float* luminance,
                           size_t width, size_t height, const LodestarSunDisk* sun = nullptr) {
        EnvGuide g;
        check(create(config, low, high, luminance, width, height, sun, g), "lodestar_env_guide_create");
        return g;
    }
    EnvSample sample(uint32_t cell, float u_lobe, float u0, float u1) const {
        EnvSample s{};
        check(sample(cell, u_lobe, u0, u1, s), "lodestar_env_guide_sample");
        return s;
    }
#endif
};

}  // namespace lodestar

#endif  // LODESTAR_HPP
