// lodestar.hpp built with -fno-exceptions: only the status-returning forms exist. Creates
// every structure and the light and environment guides through the wrapper, checks that
// errors come back as statuses with the library's message, that handles move (the moved
// from one is empty) and release on scope exit (valgrind checks no leak). Prints one line
// per failed check and "status_only: N checks passed" at the end.
#include <cstdio>
#include <cstring>
#include <vector>

#include "lodestar.hpp"

namespace {
int checks = 0, failures = 0;
void truth(bool condition, const char* what, int line) {
    ++checks;
    if (!condition) {
        std::printf("line %d: %s does not hold (%s)\n", line, what, lodestar::last_error().c_str());
        ++failures;
    }
}
#define TRUTH(condition) truth((condition), #condition, __LINE__)
#define OK(call) TRUTH((call) == LODESTAR_STATUS_OK)

// Locates, samples, learns, rebuilds, saves and reloads one guide through the wrapper.
void exercise(lodestar::Guide& guide, uint32_t structure) {
    uint32_t found = 0;
    OK(guide.structure(found));
    TRUTH(found == structure);
    lodestar::Region region{};
    OK(guide.locate({0.5f, 0.2f, 0.5f}, {0, 1, 0}, region));
    TRUTH(region.index != LODESTAR_NO_REGION);
    lodestar::DirectionSample sample{};
    OK(guide.sample(region, 0.3f, 0.6f, sample));
    float pdf = 0;
    OK(guide.pdf(region, sample.direction, pdf));
    TRUTH(sample.pdf > 0 && pdf > 0);
    LodestarUpdateOutcome outcome{};
    TRUTH(guide.update_sampled(region, sample.direction, -1.0f, sample.pdf, outcome) ==
          LODESTAR_STATUS_INVALID_ARGUMENT);
    TRUTH(std::strstr(lodestar::last_error().c_str(), "target") != nullptr);
    OK(guide.update_sampled(region, sample.direction, 2.0f, sample.pdf, outcome));
    OK(guide.rebuild());
    OK(guide.validate());
    lodestar::Guide copy;
    std::vector<uint8_t> snapshot;
    OK(guide.save(snapshot));
    OK(lodestar::Guide::load(snapshot, copy));
    OK(copy.reset());
    LodestarGuideStats reset_stats{};
    OK(copy.stats(reset_stats));
    TRUTH(reset_stats.accepted_updates == 0);
    std::vector<uint8_t> bytes;
    OK(guide.save(bytes));
    TRUTH(!bytes.empty());
    lodestar::Guide loaded;
    OK(lodestar::Guide::load(bytes, loaded));
    lodestar::Guide moved = std::move(loaded);
    TRUTH(!loaded && moved);
    // Every structure merges (a rebuilt guide into its own copy).
    OK(moved.merge(guide));
    OK(moved.structure(found));
    TRUTH(found == structure);
    bytes[bytes.size() / 2] ^= 1;
    TRUTH(lodestar::Guide::load(bytes, loaded) == LODESTAR_STATUS_DECODE_FAILED && !loaded);
}
}  // namespace

int main() {
    const LodestarVec3 low{0, 0, 0}, high{1, 1, 1};
    {
        LodestarGuideConfig config;
        OK(lodestar_guide_config_default(&config));
        config.region_count = 8;
        const std::vector<float> floor{0, 0, 0, 0, 0, 1, 1, 0, 1, 1, 0, 0};
        const std::vector<uint32_t> indices{0, 1, 2, 0, 2, 3};
        lodestar::Guide guide;
        config.struct_size = 1;
        TRUTH(lodestar::Guide::create(config, floor, indices, guide) == LODESTAR_STATUS_WRONG_STRUCT_SIZE && !guide);
        config.struct_size = sizeof config;
        OK(lodestar::Guide::create(config, floor, indices, guide));
        exercise(guide, LODESTAR_STRUCTURE_HEMISPHERE_GRID);
    }
    {
        LodestarVolumeConfig config;
        OK(lodestar_volume_config_default(&config));
        config.budget_bytes = 128 << 10;
        lodestar::Guide guide;
        OK(lodestar::Guide::create_volume(config, low, high, guide));
        exercise(guide, LODESTAR_STRUCTURE_IRRADIANCE_VOLUME);
    }
    {
        LodestarMixtureConfig config;
        OK(lodestar_mixture_config_default(&config));
        config.budget_bytes = 128 << 10;
        lodestar::Guide guide;
        OK(lodestar::Guide::create_mixture(config, low, high, guide));
        exercise(guide, LODESTAR_STRUCTURE_GAUSSIAN_MIXTURE);
    }
    {
        LodestarTreeConfig config;
        OK(lodestar_tree_config_default(&config));
        config.budget_bytes = 1 << 20;
        lodestar::Guide guide;
        TRUTH(lodestar::Guide::create_tree(config, high, low, guide) == LODESTAR_STATUS_INVALID_ARGUMENT);
        TRUTH(std::strstr(lodestar::last_error().c_str(), "below") != nullptr);
        OK(lodestar::Guide::create_tree(config, low, high, guide));
        exercise(guide, LODESTAR_STRUCTURE_SPATIAL_DIRECTIONAL_TREE);
        lodestar::PathRecorder recorder;
        OK(lodestar::PathRecorder::create(recorder));
        lodestar::Region region{};
        OK(guide.locate({0.5f, 0.5f, 0.5f}, {0, 0, 1}, region));
        OK(recorder.scattered(region, {0.5f, 0.5f, 0.5f}, {0, 0, 1}, 0.5f, 1.0f));
        OK(recorder.arrive(3.0f));
        size_t accepted = 0;
        OK(recorder.learn(guide, accepted));
        TRUTH(accepted == 1);
    }
    {
        LodestarLightGuideConfig config;
        OK(lodestar_light_guide_config_default(&config));
        lodestar::LightGuide lights;
        OK(lodestar::LightGuide::create(config, low, high, {1.0f, 3.0f}, lights));
        uint32_t cell = 0, light = 9;
        float probability = 0;
        OK(lights.cell({0.5f, 0.5f, 0.5f}, cell));
        OK(lights.select(cell, 0.9f, light, probability));
        TRUTH(light < 2 && probability > 0);
        std::vector<uint8_t> bytes;
        OK(lights.save(bytes));
        lodestar::LightGuide loaded;
        OK(lodestar::LightGuide::load(bytes, loaded));
        OK(loaded.merge(lights));
        TRUTH(loaded.merge(loaded) == LODESTAR_STATUS_INVALID_ARGUMENT);
    }
    {
        LodestarEnvGuideConfig config;
        OK(lodestar_env_guide_config_default(&config));
        config.tiles[0] = 4;
        config.tiles[1] = 2;
        const std::vector<float> sky(8 * 4, 1.0f);
        lodestar::EnvGuide env;
        TRUTH(lodestar::EnvGuide::create(config, low, high, nullptr, 8, 4, nullptr, env) ==
              LODESTAR_STATUS_NULL_ARGUMENT);
        OK(lodestar::EnvGuide::create(config, low, high, sky.data(), 8, 4, nullptr, env));
        uint32_t cell = 0;
        OK(env.cell({0.5f, 0.5f, 0.5f}, cell));
        lodestar::EnvSample sample{};
        OK(env.sample(cell, 0.4f, 0.5f, 0.5f, sample));
        float pdf = 0;
        OK(env.pdf(cell, sample.direction, pdf));
        TRUTH(sample.pdf > 0 && pdf > 0);
        LodestarUpdateOutcome outcome{};
        OK(env.update(cell, sample, 1.0f, outcome));
        OK(env.rebuild());
    }
    std::printf("status_only: %d of %d checks passed\n", checks - failures, checks);
    return failures == 0 ? 0 : 1;
}
