/* Every error path of Lodestar's C API, called from C: NULL pointers, NaN and infinite
 * numbers, out-of-range arguments, wrong struct sizes, unknown enum values, stale
 * regions, small and corrupted buffers, the path recorder's calls, the volume, mixture and
 * tree made over scene bounds, and the light and environment guides'. Each check asserts the status code and that
 * lodestar_last_error() names the culprit; a final part updates one guide from four
 * threads at once. Prints one line per failed check and exits non-zero on any. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lodestar.h"

static int checks = 0, failures = 0;

/* The status must be `expected` and, on failure, the message must contain `needle`. */
static void expect(LodestarStatus status, LodestarStatus expected, const char *needle, int line) {
    ++checks;
    const char *message = lodestar_last_error();
    if (status != expected) {
        printf("line %d: got %s, expected %s (%s)\n", line, lodestar_status_name(status),
               lodestar_status_name(expected), message);
        ++failures;
    } else if (expected == LODESTAR_STATUS_OK ? message[0] != '\0' : strstr(message, needle) == NULL) {
        printf("line %d: message \"%s\" does not mention \"%s\"\n", line, message, needle);
        ++failures;
    }
}
#define EXPECT(call, expected, needle) expect((call), (expected), (needle), __LINE__)
#define EXPECT_OK(call) expect((call), LODESTAR_STATUS_OK, "", __LINE__)

static void truth(int condition, const char *what, int line) {
    ++checks;
    if (!condition) {
        printf("line %d: %s does not hold\n", line, what);
        ++failures;
    }
}
#define TRUTH(condition) truth((condition), #condition, __LINE__)

/* A unit floor quad facing +y. */
static const float floor_positions[] = {0, 0, 0, 0, 0, 1, 1, 0, 1, 1, 0, 0};
static const uint32_t floor_indices[] = {0, 1, 2, 0, 2, 3};

static float lambert_cos(void *user_data, LodestarVec3 wi, LodestarVec3 wo) {
    (void)wo;
    const float albedo = *(const float *)user_data;
    return wi.y > 0 ? albedo / 3.14159265f * wi.y : 0.0f;
}
static float returns_nan(void *user_data, LodestarVec3 wi, LodestarVec3 wo) {
    (void)user_data, (void)wi, (void)wo;
    return NAN;
}
static float returns_negative(void *user_data, LodestarVec3 wi, LodestarVec3 wo) {
    (void)user_data, (void)wi, (void)wo;
    return -0.5f;
}

static void config_errors(void) {
    const float *p = floor_positions;
    const uint32_t *ix = floor_indices;
    LodestarGuideConfig config, bad;
    LodestarGuide *guide = NULL;
    EXPECT(lodestar_guide_config_default(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_config");
    EXPECT_OK(lodestar_guide_config_default(&config));
    TRUTH(config.struct_size == sizeof(LodestarGuideConfig));

    EXPECT(lodestar_guide_create(NULL, p, 4, ix, 2, &guide), LODESTAR_STATUS_NULL_ARGUMENT, "config");
    EXPECT(lodestar_guide_create(&config, NULL, 4, ix, 2, &guide), LODESTAR_STATUS_NULL_ARGUMENT, "positions");
    EXPECT(lodestar_guide_create(&config, p, 4, NULL, 2, &guide), LODESTAR_STATUS_NULL_ARGUMENT, "indices");
    EXPECT(lodestar_guide_create(&config, p, 4, ix, 2, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_guide");

    bad = config, bad.struct_size = 12;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_WRONG_STRUCT_SIZE, "struct_size");
    bad = config, bad.structure = 99;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_UNKNOWN_ENUM_VALUE, "structure");
    bad = config, bad.mapping = 5;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_UNKNOWN_ENUM_VALUE, "mapping");
    bad = config, bad.learning_rate = 0xFFFFFFFFu;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_UNKNOWN_ENUM_VALUE, "learning_rate");
    bad = config, bad.integral_estimator = 5;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_UNKNOWN_ENUM_VALUE,
           "integral_estimator");
    bad = config, bad.initial_q = NAN;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "initial_q");
    bad = config, bad.learning_rate = LODESTAR_LEARNING_RATE_EXPONENTIAL, bad.learning_rate_parameter = INFINITY;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_NON_FINITE_ARGUMENT,
           "learning_rate_parameter");
    bad = config, bad.learning_rate = LODESTAR_LEARNING_RATE_EXPONENTIAL, bad.learning_rate_parameter = 1.5f;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_INVALID_CONFIG, "alpha");
    bad = config, bad.budget_bytes = 100;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_INVALID_CONFIG, "budget");
    bad = config, bad.resolution[0] = 1024, bad.resolution[1] = 1024;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_INVALID_CONFIG, "resolution");
    bad = config, bad.two_sided = 7;
    EXPECT(lodestar_guide_create(&bad, p, 4, ix, 2, &guide), LODESTAR_STATUS_INVALID_ARGUMENT, "two_sided");

    const uint32_t past_end[] = {0, 1, 9};
    EXPECT(lodestar_guide_create(&config, p, 4, past_end, 1, &guide), LODESTAR_STATUS_INVALID_ARGUMENT, "indices[2]");
    float nan_vertex[12];
    memcpy(nan_vertex, floor_positions, sizeof nan_vertex);
    nan_vertex[4] = NAN;
    EXPECT(lodestar_guide_create(&config, nan_vertex, 4, ix, 2, &guide), LODESTAR_STATUS_NON_FINITE_ARGUMENT,
           "vertex 1");
    const float collapsed[] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    const uint32_t one[] = {0, 1, 2};
    EXPECT(lodestar_guide_create(&config, collapsed, 3, one, 1, &guide), LODESTAR_STATUS_INVALID_GEOMETRY, "area");
    EXPECT(lodestar_guide_create(&config, p, 4, ix, 0, &guide), LODESTAR_STATUS_INVALID_GEOMETRY, "area");
    TRUTH(guide == NULL); /* nothing was written by any failed call */
}

static void per_vertex_errors(LodestarGuide *guide) {
    LodestarVec3 up = {0, 1, 0}, centre = {0.5f, 0, 0.5f}, zero = {0, 0, 0}, nan3 = {NAN, 0, 0};
    LodestarVec3 inf3 = {0, INFINITY, 0};
    LodestarRegion region, none = {LODESTAR_NO_REGION, 0, {0, 1, 0}}, past = {1u << 30, 0, {0, 1, 0}};
    LodestarDirectionSample sample;
    LodestarUpdateOutcome outcome;
    float value = 0, albedo = 0.5f;

    EXPECT(lodestar_guide_locate(NULL, centre, up, &region), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT(lodestar_guide_locate(guide, centre, up, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_region");
    EXPECT(lodestar_guide_locate(guide, nan3, up, &region), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "position");
    EXPECT(lodestar_guide_locate(guide, centre, inf3, &region), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "normal");
    EXPECT(lodestar_guide_locate(guide, centre, zero, &region), LODESTAR_STATUS_INVALID_ARGUMENT, "normal");
    LodestarVec3 far_away = {1e6f, 0, 0}, down = {0, -1, 0};
    EXPECT_OK(lodestar_guide_locate(guide, far_away, up, &region));
    TRUTH(region.index == LODESTAR_NO_REGION);
    EXPECT_OK(lodestar_guide_locate(guide, centre, down, &region));
    TRUTH(region.index == LODESTAR_NO_REGION); /* one-sided: nothing faces down */
    EXPECT_OK(lodestar_guide_locate(guide, centre, up, &region));
    TRUTH(region.index != LODESTAR_NO_REGION);

    EXPECT(lodestar_guide_sample(guide, region, NAN, 0.5f, &sample), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "u0");
    EXPECT(lodestar_guide_sample(guide, region, 0.5f, 1.5f, &sample), LODESTAR_STATUS_INVALID_ARGUMENT, "u1");
    EXPECT(lodestar_guide_sample(guide, none, 0.5f, 0.5f, &sample), LODESTAR_STATUS_INVALID_REGION,
           "LODESTAR_NO_REGION");
    EXPECT(lodestar_guide_sample(guide, past, 0.5f, 0.5f, &sample), LODESTAR_STATUS_INVALID_REGION, "past");
    EXPECT(lodestar_guide_sample(guide, region, 0.5f, 0.5f, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_sample");
    EXPECT_OK(lodestar_guide_sample(guide, region, 0.5f, 0.5f, &sample));
    TRUTH(sample.pdf > 0 && sample.direction.y > 0);

    EXPECT(lodestar_guide_pdf(guide, region, nan3, &value), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "direction");
    EXPECT(lodestar_guide_pdf(guide, region, zero, &value), LODESTAR_STATUS_INVALID_ARGUMENT, "direction");
    EXPECT(lodestar_guide_pdf(guide, past, up, &value), LODESTAR_STATUS_INVALID_REGION, "region");
    EXPECT_OK(lodestar_guide_pdf(guide, region, sample.direction, &value));
    TRUTH(value == sample.pdf);

    LodestarGuideStats before, after;
    EXPECT_OK(lodestar_guide_stats(guide, &before));
    EXPECT(lodestar_guide_update(guide, region, up, NAN, &outcome), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "target");
    EXPECT(lodestar_guide_update(guide, region, up, INFINITY, &outcome), LODESTAR_STATUS_NON_FINITE_ARGUMENT,
           "target");
    EXPECT(lodestar_guide_update(guide, region, up, -1.0f, &outcome), LODESTAR_STATUS_INVALID_ARGUMENT, "negative");
    EXPECT(lodestar_guide_update(guide, region, nan3, 1.0f, &outcome), LODESTAR_STATUS_NON_FINITE_ARGUMENT,
           "direction");
    EXPECT(lodestar_guide_update(guide, none, up, 1.0f, &outcome), LODESTAR_STATUS_INVALID_REGION, "region");
    EXPECT(lodestar_guide_update(guide, region, up, 1.0f, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_outcome");
    EXPECT_OK(lodestar_guide_stats(guide, &after));
    TRUTH(after.rejected_non_finite == before.rejected_non_finite + 2);
    TRUTH(after.rejected_negative == before.rejected_negative + 1);
    TRUTH(after.accepted_updates == before.accepted_updates); /* nothing stored */
    EXPECT_OK(lodestar_guide_update(guide, region, up, 3.0f, &outcome));
    TRUTH(outcome == LODESTAR_UPDATE_OUTCOME_ACCEPTED);
    EXPECT_OK(lodestar_guide_update(guide, region, down, 3.0f, &outcome));
    TRUTH(outcome == LODESTAR_UPDATE_OUTCOME_OUTSIDE_DOMAIN);

    EXPECT(lodestar_guide_estimate_integral(guide, region, up, NULL, &albedo, 0.5f, 0.5f, &value),
           LODESTAR_STATUS_NULL_ARGUMENT, "eval_cos");
    EXPECT(lodestar_guide_estimate_integral(guide, region, up, returns_nan, NULL, 0.5f, 0.5f, &value),
           LODESTAR_STATUS_NON_FINITE_ARGUMENT, "`eval_cos` returned NaN");
    EXPECT(lodestar_guide_estimate_integral(guide, region, up, returns_negative, NULL, 0.5f, 0.5f, &value),
           LODESTAR_STATUS_INVALID_ARGUMENT, "`eval_cos` returned -0.5");
    EXPECT(lodestar_guide_estimate_integral(guide, region, nan3, lambert_cos, &albedo, 0.5f, 0.5f, &value),
           LODESTAR_STATUS_NON_FINITE_ARGUMENT, "wo");
    EXPECT(lodestar_guide_estimate_integral_lambertian(guide, region, up, NAN, 0.5f, 0.5f, &value),
           LODESTAR_STATUS_NON_FINITE_ARGUMENT, "albedo");
    EXPECT(lodestar_guide_estimate_integral_lambertian(guide, region, up, 2.0f, 0.5f, 0.5f, &value),
           LODESTAR_STATUS_INVALID_ARGUMENT, "albedo");
    EXPECT(lodestar_guide_estimate_integral_lambertian(guide, region, zero, 0.5f, 0.5f, 0.5f, &value),
           LODESTAR_STATUS_INVALID_ARGUMENT, "normal");
    /* The callback and the Lambertian fast path estimate the same integral. */
    float through_callback = 0, exact = 0;
    EXPECT_OK(lodestar_guide_estimate_integral(guide, region, up, lambert_cos, &albedo, 0.5f, 0.5f, &through_callback));
    EXPECT_OK(lodestar_guide_estimate_integral_lambertian(guide, region, up, albedo, 0.5f, 0.5f, &exact));
    TRUTH(exact > 0 && fabsf(through_callback - exact) < 0.05f * exact);

    EXPECT(lodestar_guide_stats(guide, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_stats");
    EXPECT(lodestar_guide_stats(NULL, &after), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT(lodestar_guide_validate(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT(lodestar_guide_rebuild(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT(lodestar_guide_release(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT_OK(lodestar_guide_rebuild(guide));
    EXPECT_OK(lodestar_guide_validate(guide));
}

/* The path recorder: its error paths, and a recorded path that teaches the guide. */
static void recorder_errors(LodestarGuide *guide) {
    LodestarVec3 up = {0, 1, 0}, centre = {0.5f, 0, 0.5f}, zero = {0, 0, 0}, nan3 = {NAN, 0, 0};
    LodestarRegion region, none = {LODESTAR_NO_REGION, 0, {0, 1, 0}}, past = {1u << 30, 0, {0, 1, 0}};
    LodestarPathRecorder *recorder = NULL;
    size_t accepted = 99;

    EXPECT(lodestar_path_recorder_create(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_recorder");
    EXPECT_OK(lodestar_path_recorder_create(&recorder));
    EXPECT_OK(lodestar_guide_locate(guide, centre, up, &region));
    EXPECT(lodestar_path_recorder_scattered(NULL, region, centre, up, 1.0f, 1.0f), LODESTAR_STATUS_NULL_ARGUMENT,
           "recorder");
    EXPECT(lodestar_path_recorder_scattered(recorder, region, nan3, up, 1.0f, 1.0f),
           LODESTAR_STATUS_NON_FINITE_ARGUMENT, "origin");
    EXPECT(lodestar_path_recorder_scattered(recorder, region, centre, zero, 1.0f, 1.0f),
           LODESTAR_STATUS_INVALID_ARGUMENT, "direction");
    EXPECT(lodestar_path_recorder_scattered(recorder, region, centre, up, 0.0f, 1.0f), LODESTAR_STATUS_INVALID_ARGUMENT,
           "pdf");
    EXPECT(lodestar_path_recorder_scattered(recorder, region, centre, up, NAN, 1.0f),
           LODESTAR_STATUS_NON_FINITE_ARGUMENT, "pdf");
    EXPECT(lodestar_path_recorder_scattered(recorder, region, centre, up, 1.0f, -1.0f),
           LODESTAR_STATUS_INVALID_ARGUMENT, "throughput");
    EXPECT(lodestar_path_recorder_reached(recorder, NAN), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "distance");
    EXPECT(lodestar_path_recorder_arrive(recorder, -2.0f), LODESTAR_STATUS_INVALID_ARGUMENT, "radiance");
    EXPECT(lodestar_path_recorder_arrive(recorder, INFINITY), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "radiance");
    EXPECT(lodestar_path_recorder_estimate(recorder, NAN), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "integral");
    EXPECT(lodestar_path_recorder_carry(recorder, -1.0f), LODESTAR_STATUS_INVALID_ARGUMENT, "factor");
    EXPECT(lodestar_path_recorder_clear(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "recorder");
    EXPECT(lodestar_path_recorder_learn(recorder, NULL, &accepted), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT(lodestar_path_recorder_learn(recorder, guide, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_accepted");

    /* Nothing recorded: nothing learned. */
    EXPECT_OK(lodestar_path_recorder_learn(recorder, guide, &accepted));
    TRUTH(accepted == 0);

    /* A two-vertex path: the first vertex carries the second's target; the second has no
     * region and learns nothing. A stale region fails the whole path. */
    LodestarGuideStats before, after;
    EXPECT_OK(lodestar_guide_stats(guide, &before));
    EXPECT_OK(lodestar_path_recorder_scattered(recorder, past, centre, up, 0.5f, 1.0f));
    EXPECT(lodestar_path_recorder_learn(recorder, guide, &accepted), LODESTAR_STATUS_INVALID_REGION, "vertex 0");
    EXPECT_OK(lodestar_path_recorder_clear(recorder));
    EXPECT_OK(lodestar_path_recorder_scattered(recorder, region, centre, up, 0.5f, 1.0f));
    EXPECT_OK(lodestar_path_recorder_reached(recorder, 1.0f));
    EXPECT_OK(lodestar_path_recorder_carry(recorder, 0.8f));
    EXPECT_OK(lodestar_path_recorder_scattered(recorder, none, up, up, 1.0f, 0.8f));
    EXPECT_OK(lodestar_path_recorder_arrive(recorder, 2.0f));
    EXPECT_OK(lodestar_path_recorder_learn(recorder, guide, &accepted));
    TRUTH(accepted == 1);
    EXPECT_OK(lodestar_guide_stats(guide, &after));
    TRUTH(after.accepted_updates == before.accepted_updates + 1);

    EXPECT(lodestar_path_recorder_release(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "recorder");
    EXPECT_OK(lodestar_path_recorder_release(recorder));
}

static void buffer_errors(LodestarGuide *guide) {
    size_t size = 0, written = 0;
    EXPECT(lodestar_guide_serialized_size(guide, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_size");
    EXPECT_OK(lodestar_guide_serialized_size(guide, &size));
    uint8_t *bytes = malloc(size);
    EXPECT(lodestar_guide_save(guide, NULL, size, &written), LODESTAR_STATUS_NULL_ARGUMENT, "buffer");
    EXPECT(lodestar_guide_save(guide, bytes, size - 1, &written), LODESTAR_STATUS_BUFFER_TOO_SMALL, "capacity");
    TRUTH(written == size); /* the size needed */
    written = 0;
    EXPECT_OK(lodestar_guide_save(guide, bytes, size, &written));
    TRUTH(written == size);

    LodestarGuide *loaded = NULL;
    EXPECT(lodestar_guide_load(NULL, size, &loaded), LODESTAR_STATUS_NULL_ARGUMENT, "bytes");
    EXPECT(lodestar_guide_load(bytes, size, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_guide");
    EXPECT(lodestar_guide_load(bytes, 0, &loaded), LODESTAR_STATUS_DECODE_FAILED, "magic");
    EXPECT(lodestar_guide_load(bytes, size / 2, &loaded), LODESTAR_STATUS_DECODE_FAILED, "damaged");
    bytes[size / 2] ^= 0x40; /* one flipped bit inside the tables */
    EXPECT(lodestar_guide_load(bytes, size, &loaded), LODESTAR_STATUS_DECODE_FAILED, "checksum");
    bytes[size / 2] ^= 0x40;
    bytes[0] = 'X';
    EXPECT(lodestar_guide_load(bytes, size, &loaded), LODESTAR_STATUS_DECODE_FAILED, "magic");
    bytes[0] = 'L';
    uint8_t *longer = calloc(size + 3, 1);
    memcpy(longer, bytes, size);
    EXPECT(lodestar_guide_load(longer, size + 3, &loaded), LODESTAR_STATUS_DECODE_FAILED, "");
    free(longer);
    TRUTH(loaded == NULL);

    EXPECT_OK(lodestar_guide_load(bytes, size, &loaded));
    LodestarGuideStats original, copy;
    EXPECT_OK(lodestar_guide_stats(guide, &original));
    EXPECT_OK(lodestar_guide_stats(loaded, &copy));
    TRUTH(original.regions == copy.regions && original.entries_per_region == copy.entries_per_region);
    TRUTH(original.accepted_updates == copy.accepted_updates && original.visited_entries == copy.visited_entries);
    TRUTH(original.rejected_non_finite == copy.rejected_non_finite && original.epochs == copy.epochs);
    /* Merging: every structure takes in its own copy (twice the updates). A tree or a
       mixture merges what it learned through its last rebuild. */
    uint32_t structure = 0;
    EXPECT_OK(lodestar_guide_structure(guide, &structure));
    EXPECT(lodestar_guide_merge(guide, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "other");
    EXPECT(lodestar_guide_merge(guide, guide), LODESTAR_STATUS_INVALID_ARGUMENT, "itself");
    EXPECT_OK(lodestar_guide_rebuild(guide));
    EXPECT_OK(lodestar_guide_rebuild(loaded));
    EXPECT_OK(lodestar_guide_stats(guide, &original)); /* a volume's rebuild may split */
    EXPECT_OK(lodestar_guide_merge(guide, loaded));
    EXPECT_OK(lodestar_guide_stats(guide, &copy));
    TRUTH(copy.accepted_updates == 2 * original.accepted_updates);
    EXPECT_OK(lodestar_guide_validate(guide));
    /* Reset: the copy forgets everything and serializes as a fresh guide of its kind. */
    EXPECT(lodestar_guide_reset(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT_OK(lodestar_guide_reset(loaded));
    EXPECT_OK(lodestar_guide_validate(loaded));
    EXPECT_OK(lodestar_guide_stats(loaded, &copy));
    TRUTH(copy.accepted_updates == 0 && copy.rejected_non_finite == 0 && copy.epochs == 0);
    EXPECT_OK(lodestar_guide_release(loaded));
    free(bytes);
}

/* Four threads update one region at once: no update is lost. */
typedef struct {
    LodestarGuide *guide;
    LodestarRegion region;
    int failed;
} Worker;

static void *update_many(void *argument) {
    Worker *worker = argument;
    LodestarVec3 direction = {0.3f, 0.9f, 0.1f};
    LodestarUpdateOutcome outcome;
    for (int i = 0; i < 10000; ++i)
        if (lodestar_guide_update(worker->guide, worker->region, direction, (float)(i % 7), &outcome) !=
            LODESTAR_STATUS_OK)
            worker->failed = 1;
    return NULL;
}

static void concurrent_updates(LodestarGuide *guide) {
    LodestarVec3 up = {0, 1, 0}, centre = {0.5f, 0, 0.5f};
    LodestarRegion region;
    LodestarGuideStats before, after;
    EXPECT_OK(lodestar_guide_locate(guide, centre, up, &region));
    EXPECT_OK(lodestar_guide_stats(guide, &before));
    pthread_t threads[4];
    Worker workers[4];
    for (int t = 0; t < 4; ++t) {
        workers[t] = (Worker){guide, region, 0};
        pthread_create(&threads[t], NULL, update_many, &workers[t]);
    }
    for (int t = 0; t < 4; ++t) {
        pthread_join(threads[t], NULL);
        TRUTH(!workers[t].failed);
    }
    EXPECT_OK(lodestar_guide_stats(guide, &after));
    TRUTH(after.accepted_updates == before.accepted_updates + 40000);
    EXPECT_OK(lodestar_guide_rebuild(guide));
    EXPECT_OK(lodestar_guide_validate(guide));
}

/* The light guide: its config, every call's bad arguments, learning that moves the
 * selection towards the light that arrives, and a save/load round trip. */
static void light_guide_errors(void) {
    LodestarLightGuideConfig config;
    LodestarLightGuide *lights = NULL;
    const float powers[] = {1.0f, 1.0f, 2.0f};
    LodestarVec3 low = {0, 0, 0}, high = {4, 2, 1}, inside = {1, 1, 0.5f}, nan_point = {NAN, 0, 0};
    EXPECT(lodestar_light_guide_config_default(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_config");
    EXPECT_OK(lodestar_light_guide_config_default(&config));
    config.rule = 7;
    EXPECT(lodestar_light_guide_create(&config, low, high, powers, 3, &lights), LODESTAR_STATUS_UNKNOWN_ENUM_VALUE,
           "rule");
    config.rule = LODESTAR_LIGHT_RULE_MEAN_CONTRIBUTION;
    config.struct_size = 8;
    EXPECT(lodestar_light_guide_create(&config, low, high, powers, 3, &lights), LODESTAR_STATUS_WRONG_STRUCT_SIZE,
           "struct_size");
    EXPECT_OK(lodestar_light_guide_config_default(&config));
    config.uniform_mix = NAN;
    EXPECT(lodestar_light_guide_create(&config, low, high, powers, 3, &lights), LODESTAR_STATUS_NON_FINITE_ARGUMENT,
           "uniform_mix");
    EXPECT_OK(lodestar_light_guide_config_default(&config));
    EXPECT(lodestar_light_guide_create(NULL, low, high, powers, 3, &lights), LODESTAR_STATUS_NULL_ARGUMENT, "config");
    EXPECT(lodestar_light_guide_create(&config, low, high, NULL, 3, &lights), LODESTAR_STATUS_NULL_ARGUMENT, "powers");
    EXPECT(lodestar_light_guide_create(&config, nan_point, high, powers, 3, &lights),
           LODESTAR_STATUS_NON_FINITE_ARGUMENT, "low");
    EXPECT(lodestar_light_guide_create(&config, low, high, powers, 0, &lights), LODESTAR_STATUS_INVALID_CONFIG,
           "light_count");
    const float negative[] = {1.0f, -1.0f};
    EXPECT(lodestar_light_guide_create(&config, low, high, negative, 2, &lights), LODESTAR_STATUS_INVALID_CONFIG,
           "light_powers");
    TRUTH(lights == NULL);
    EXPECT_OK(lodestar_light_guide_create(&config, low, high, powers, 3, &lights));

    uint32_t cell = 0, light = 0;
    float probability = 0;
    LodestarUpdateOutcome outcome;
    EXPECT(lodestar_light_guide_cell(NULL, inside, &cell), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT(lodestar_light_guide_cell(lights, nan_point, &cell), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "position");
    EXPECT_OK(lodestar_light_guide_cell(lights, inside, &cell));
    EXPECT(lodestar_light_guide_select(lights, cell, 1.5f, &light, &probability), LODESTAR_STATUS_INVALID_ARGUMENT,
           "`u`");
    EXPECT(lodestar_light_guide_select(lights, 1u << 30, 0.5f, &light, &probability),
           LODESTAR_STATUS_INVALID_ARGUMENT, "cell");
    EXPECT(lodestar_light_guide_select(lights, cell, 0.5f, NULL, &probability), LODESTAR_STATUS_NULL_ARGUMENT,
           "out_light");
    EXPECT(lodestar_light_guide_probability(lights, cell, 3, &probability), LODESTAR_STATUS_INVALID_ARGUMENT, "light");
    EXPECT(lodestar_light_guide_update(lights, cell, 0, NAN, 1, &outcome), LODESTAR_STATUS_NON_FINITE_ARGUMENT,
           "contribution");
    EXPECT(lodestar_light_guide_update(lights, cell, 0, -1.0f, 1, &outcome), LODESTAR_STATUS_INVALID_ARGUMENT,
           "negative");
    EXPECT(lodestar_light_guide_update(lights, cell, 0, 1.0f, 2, &outcome), LODESTAR_STATUS_INVALID_ARGUMENT,
           "unoccluded");
    EXPECT(lodestar_light_guide_rebuild(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "guide");

    /* Only light 0 ever arrives from this cell: after a rebuild it is the likeliest. */
    int learned = 1;
    for (int i = 0; i < 200; ++i) {
        learned &= lodestar_light_guide_update(lights, cell, 0, 5.0f, 1, &outcome) == LODESTAR_STATUS_OK;
        learned &= lodestar_light_guide_update(lights, cell, 2, 5.0f, 0, &outcome) == LODESTAR_STATUS_OK;
    }
    TRUTH(learned);
    EXPECT_OK(lodestar_light_guide_rebuild(lights));
    float p0 = 0, p2 = 0;
    EXPECT_OK(lodestar_light_guide_probability(lights, cell, 0, &p0));
    EXPECT_OK(lodestar_light_guide_probability(lights, cell, 2, &p2));
    TRUTH(p0 > 0.6f && p2 > 0.0f);
    EXPECT_OK(lodestar_light_guide_select(lights, cell, 0.1f, &light, &probability));
    float again = 0;
    EXPECT_OK(lodestar_light_guide_probability(lights, cell, light, &again));
    TRUTH(again == probability);

    size_t size = 0, written = 0;
    EXPECT_OK(lodestar_light_guide_save(lights, NULL, 0, &size));
    uint8_t *bytes = malloc(size);
    EXPECT(lodestar_light_guide_save(lights, bytes, size - 1, &written), LODESTAR_STATUS_BUFFER_TOO_SMALL, "capacity");
    EXPECT_OK(lodestar_light_guide_save(lights, bytes, size, &written));
    TRUTH(written == size);
    LodestarLightGuide *loaded = NULL;
    bytes[size / 2] ^= 0x10;
    EXPECT(lodestar_light_guide_load(bytes, size, &loaded), LODESTAR_STATUS_DECODE_FAILED, "checksum");
    bytes[size / 2] ^= 0x10;
    EXPECT(lodestar_light_guide_load(bytes, size - 9, &loaded), LODESTAR_STATUS_DECODE_FAILED, "");
    EXPECT_OK(lodestar_light_guide_load(bytes, size, &loaded));
    float loaded_p0 = 0;
    EXPECT_OK(lodestar_light_guide_probability(loaded, cell, 0, &loaded_p0));
    TRUTH(loaded_p0 == p0);
    /* Merging its own copy keeps every mean: the probabilities stay. */
    EXPECT(lodestar_light_guide_merge(lights, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "other");
    EXPECT(lodestar_light_guide_merge(lights, lights), LODESTAR_STATUS_INVALID_ARGUMENT, "itself");
    EXPECT_OK(lodestar_light_guide_merge(loaded, lights));
    EXPECT_OK(lodestar_light_guide_probability(loaded, cell, 0, &loaded_p0));
    TRUTH(fabsf(loaded_p0 - p0) <= 1e-6f);
    LodestarLightGuide *elsewhere = NULL;
    LodestarVec3 far_high = {8, 2, 1};
    EXPECT_OK(lodestar_light_guide_create(&config, low, far_high, powers, 3, &elsewhere));
    EXPECT(lodestar_light_guide_merge(loaded, elsewhere), LODESTAR_STATUS_INVALID_ARGUMENT, "bounds");
    EXPECT_OK(lodestar_light_guide_release(elsewhere));
    EXPECT(lodestar_light_guide_reset(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT_OK(lodestar_light_guide_reset(loaded));
    float reset_p2 = 0;
    EXPECT_OK(lodestar_light_guide_probability(loaded, cell, 2, &reset_p2));
    TRUTH(reset_p2 > 0.4f); /* by power again: light 2 has half of it */
    EXPECT_OK(lodestar_light_guide_release(loaded));
    free(bytes);
    EXPECT_OK(lodestar_light_guide_release(lights));
}

/* The structures made over scene bounds (volume, mixture, tree): config and bounds
 * errors, regions that carry the normal, sampling against the pdf, the density-weighted
 * update, and the recorder and save/load paths the hemisphere grid runs through. */
static void bounded_structure_errors(void) {
    LodestarVec3 low = {0, 0, 0}, high = {1, 1, 1}, nan3 = {NAN, 0, 0}, up = {0, 1, 0};
    LodestarVec3 inside = {0.5f, 0.25f, 0.5f}, outside = {3, 0.5f, 0.5f}, zero = {0, 0, 0};
    for (uint32_t structure = LODESTAR_STRUCTURE_IRRADIANCE_VOLUME;
         structure <= LODESTAR_STRUCTURE_SPATIAL_DIRECTIONAL_TREE; ++structure) {
        LodestarGuide *guide = NULL;
        LodestarVolumeConfig volume;
        LodestarMixtureConfig mixture;
        LodestarTreeConfig tree;
        if (structure == LODESTAR_STRUCTURE_IRRADIANCE_VOLUME) {
            EXPECT(lodestar_volume_config_default(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_config");
            EXPECT_OK(lodestar_volume_config_default(&volume));
            volume.budget_bytes = 256 << 10;
            volume.struct_size = 8;
            EXPECT(lodestar_guide_create_volume(&volume, low, high, &guide), LODESTAR_STATUS_WRONG_STRUCT_SIZE,
                   "LodestarVolumeConfig");
            volume.struct_size = sizeof volume;
            volume.sphere_resolution[0] = 0;
            EXPECT(lodestar_guide_create_volume(&volume, low, high, &guide), LODESTAR_STATUS_INVALID_CONFIG, "");
            volume.sphere_resolution[0] = 16;
            volume.learning_rate = 9;
            EXPECT(lodestar_guide_create_volume(&volume, low, high, &guide), LODESTAR_STATUS_UNKNOWN_ENUM_VALUE,
                   "learning_rate");
            volume.learning_rate = LODESTAR_LEARNING_RATE_SIMPLE_AVERAGE;
            EXPECT(lodestar_guide_create_volume(NULL, low, high, &guide), LODESTAR_STATUS_NULL_ARGUMENT, "config");
            EXPECT(lodestar_guide_create_volume(&volume, nan3, high, &guide), LODESTAR_STATUS_NON_FINITE_ARGUMENT,
                   "low");
            EXPECT(lodestar_guide_create_volume(&volume, high, low, &guide), LODESTAR_STATUS_INVALID_ARGUMENT,
                   "below");
            EXPECT_OK(lodestar_guide_create_volume(&volume, low, high, &guide));
        } else if (structure == LODESTAR_STRUCTURE_GAUSSIAN_MIXTURE) {
            EXPECT_OK(lodestar_mixture_config_default(&mixture));
            mixture.budget_bytes = 256 << 10;
            mixture.lobes = 0;
            EXPECT(lodestar_guide_create_mixture(&mixture, low, high, &guide), LODESTAR_STATUS_INVALID_CONFIG,
                   "lobes");
            mixture.lobes = 2;
            mixture.split_by_normal = 2;
            EXPECT(lodestar_guide_create_mixture(&mixture, low, high, &guide), LODESTAR_STATUS_INVALID_ARGUMENT,
                   "split_by_normal");
            mixture.split_by_normal = 1;
            EXPECT(lodestar_guide_create_mixture(&mixture, low, high, NULL), LODESTAR_STATUS_NULL_ARGUMENT,
                   "out_guide");
            EXPECT_OK(lodestar_guide_create_mixture(&mixture, low, high, &guide));
        } else {
            EXPECT_OK(lodestar_tree_config_default(&tree));
            tree.budget_bytes = 1 << 20;
            tree.min_split_records = 8;
            tree.flux_fraction = NAN;
            EXPECT(lodestar_guide_create_tree(&tree, low, high, &guide), LODESTAR_STATUS_NON_FINITE_ARGUMENT,
                   "flux_fraction");
            tree.flux_fraction = 0.01f;
            tree.mixed_normal_share = NAN;
            EXPECT(lodestar_guide_create_tree(&tree, low, high, &guide), LODESTAR_STATUS_NON_FINITE_ARGUMENT,
                   "mixed_normal_share");
            tree.mixed_normal_share = 0.97f;
            tree.integral_estimator = 7;
            EXPECT(lodestar_guide_create_tree(&tree, low, high, &guide), LODESTAR_STATUS_UNKNOWN_ENUM_VALUE,
                   "integral_estimator");
            tree.integral_estimator = LODESTAR_INTEGRAL_ESTIMATOR_PATH_CONTINUATION;
            EXPECT_OK(lodestar_guide_create_tree(&tree, low, high, &guide));
        }
        uint32_t found = 0;
        EXPECT(lodestar_guide_structure(guide, NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_structure");
        EXPECT_OK(lodestar_guide_structure(guide, &found));
        TRUTH(found == structure);

        LodestarRegion region, spoiled;
        EXPECT_OK(lodestar_guide_locate(guide, outside, up, &region)); /* the nearest region */
        TRUTH(region.index != LODESTAR_NO_REGION);
        EXPECT(lodestar_guide_locate(guide, outside, zero, &region), LODESTAR_STATUS_INVALID_ARGUMENT, "normal");
        EXPECT_OK(lodestar_guide_locate(guide, inside, up, &region));
        TRUTH(region.index != LODESTAR_NO_REGION && region.normal.y == 1.0f);
        LodestarDirectionSample sample;
        float pdf = 0;
        spoiled = region;
        spoiled.normal = zero;
        EXPECT(lodestar_guide_sample(guide, spoiled, 0.5f, 0.5f, &sample), LODESTAR_STATUS_INVALID_REGION,
               "region.normal");
        spoiled.normal = nan3;
        EXPECT(lodestar_guide_pdf(guide, spoiled, up, &pdf), LODESTAR_STATUS_INVALID_REGION, "region.normal");
        for (int i = 0; i < 8; ++i) {
            EXPECT_OK(lodestar_guide_sample(guide, region, (i + 0.5f) / 8, 0.3f, &sample));
            EXPECT_OK(lodestar_guide_pdf(guide, region, sample.direction, &pdf));
            TRUTH(sample.pdf > 0 && fabsf(pdf - sample.pdf) <= 1e-3f * sample.pdf);
        }

        LodestarUpdateOutcome outcome;
        EXPECT(lodestar_guide_update_sampled(guide, region, up, 1.0f, 0.0f, &outcome),
               LODESTAR_STATUS_INVALID_ARGUMENT, "pdf");
        EXPECT(lodestar_guide_update_sampled(guide, region, up, 1.0f, NAN, &outcome),
               LODESTAR_STATUS_NON_FINITE_ARGUMENT, "pdf");
        EXPECT(lodestar_guide_update_sampled(guide, region, up, NAN, 1.0f, &outcome),
               LODESTAR_STATUS_NON_FINITE_ARGUMENT, "target");
        EXPECT(lodestar_guide_update_sampled(NULL, region, up, 1.0f, 1.0f, &outcome), LODESTAR_STATUS_NULL_ARGUMENT,
               "guide");
        /* Light from above, learned over a few passes; the guide then favours up. */
        for (int pass = 0; pass < 4; ++pass) {
            for (int i = 0; i < 256; ++i) {
                EXPECT_OK(lodestar_guide_sample(guide, region, (i + 0.5f) / 256, (i % 16 + 0.5f) / 16, &sample));
                float target = sample.direction.y > 0.9f ? 10.0f : 0.1f;
                EXPECT_OK(lodestar_guide_update_sampled(guide, region, sample.direction, target, sample.pdf,
                                                        &outcome));
            }
            EXPECT_OK(lodestar_guide_rebuild(guide));
            EXPECT_OK(lodestar_guide_locate(guide, inside, up, &region));
        }
        EXPECT_OK(lodestar_guide_validate(guide));
        float pdf_up = 0, pdf_side = 0;
        LodestarVec3 side = {1, 0.05f, 0};
        EXPECT_OK(lodestar_guide_pdf(guide, region, up, &pdf_up));
        EXPECT_OK(lodestar_guide_pdf(guide, region, side, &pdf_side));
        TRUTH(pdf_up > 2 * pdf_side);

        recorder_errors(guide);
        buffer_errors(guide);
        EXPECT_OK(lodestar_guide_release(guide));
    }
}

/* The environment guide: config, map and sun errors, sampling against the pdf, learning
 * that only the sky above arrives, and save/load for the same map (another is refused). */
static void env_guide_errors(void) {
    enum { W = 16, H = 8 };
    float luminance[W * H];
    for (int i = 0; i < W * H; ++i) luminance[i] = 1.0f;
    LodestarVec3 low = {0, 0, 0}, high = {2, 2, 2}, inside = {1, 1, 1};
    LodestarSunDisk sun = {{0.3f, 0.9f, 0.1f}, 0.05f, 1000.0f}, bad_sun = sun;
    LodestarEnvGuideConfig config;
    LodestarEnvGuide *env = NULL;
    EXPECT(lodestar_env_guide_config_default(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "out_config");
    EXPECT_OK(lodestar_env_guide_config_default(&config));
    config.tiles[0] = 8;
    config.tiles[1] = 4;
    config.budget_bytes = 64 << 10;
    config.struct_size = 3;
    EXPECT(lodestar_env_guide_create(&config, low, high, luminance, W, H, &sun, &env),
           LODESTAR_STATUS_WRONG_STRUCT_SIZE, "LodestarEnvGuideConfig");
    config.struct_size = sizeof config;
    config.uniform_mix = NAN;
    EXPECT(lodestar_env_guide_create(&config, low, high, luminance, W, H, &sun, &env),
           LODESTAR_STATUS_NON_FINITE_ARGUMENT, "uniform_mix");
    config.uniform_mix = 0.01f;
    EXPECT(lodestar_env_guide_create(&config, low, high, NULL, W, H, &sun, &env), LODESTAR_STATUS_NULL_ARGUMENT,
           "luminance");
    luminance[5] = -1.0f;
    EXPECT(lodestar_env_guide_create(&config, low, high, luminance, W, H, &sun, &env),
           LODESTAR_STATUS_INVALID_ARGUMENT, "luminance[5]");
    luminance[5] = 1.0f;
    bad_sun.angular_radius = NAN;
    EXPECT(lodestar_env_guide_create(&config, low, high, luminance, W, H, &bad_sun, &env),
           LODESTAR_STATUS_NON_FINITE_ARGUMENT, "sun->angular_radius");
    bad_sun = sun;
    bad_sun.direction = low;
    EXPECT(lodestar_env_guide_create(&config, low, high, luminance, W, H, &bad_sun, &env),
           LODESTAR_STATUS_INVALID_ARGUMENT, "sun->direction");
    EXPECT(lodestar_env_guide_create(&config, low, high, luminance, W, H, &sun, NULL), LODESTAR_STATUS_NULL_ARGUMENT,
           "out_guide");
    EXPECT_OK(lodestar_env_guide_create(&config, low, high, luminance, W, H, &sun, &env));

    uint32_t cell = 99;
    LodestarVec3 nan3 = {NAN, 0, 0};
    EXPECT(lodestar_env_guide_cell(env, nan3, &cell), LODESTAR_STATUS_NON_FINITE_ARGUMENT, "position");
    EXPECT_OK(lodestar_env_guide_cell(env, inside, &cell));
    LodestarEnvSample sample;
    float pdf = 0;
    EXPECT(lodestar_env_guide_sample(env, 1u << 20, 0.5f, 0.5f, 0.5f, &sample), LODESTAR_STATUS_INVALID_ARGUMENT,
           "cell");
    EXPECT(lodestar_env_guide_sample(env, cell, 1.5f, 0.5f, 0.5f, &sample), LODESTAR_STATUS_INVALID_ARGUMENT,
           "u_lobe");
    for (int i = 0; i < 16; ++i) {
        EXPECT_OK(lodestar_env_guide_sample(env, cell, (i + 0.5f) / 16, 0.3f, 0.7f, &sample));
        EXPECT_OK(lodestar_env_guide_pdf(env, cell, sample.direction, &pdf));
        TRUTH(sample.pdf > 0 && fabsf(pdf - sample.pdf) <= 1e-3f * sample.pdf);
    }
    EXPECT(lodestar_env_guide_pdf(env, cell, low, &pdf), LODESTAR_STATUS_INVALID_ARGUMENT, "direction");

    LodestarUpdateOutcome outcome;
    LodestarEnvSample spoiled = sample;
    spoiled.lobe = 1000;
    EXPECT(lodestar_env_guide_update(env, cell, &spoiled, 1.0f, &outcome), LODESTAR_STATUS_INVALID_ARGUMENT, "lobe");
    spoiled = sample;
    spoiled.lobe_pdf = 0;
    EXPECT(lodestar_env_guide_update(env, cell, &spoiled, 1.0f, &outcome), LODESTAR_STATUS_INVALID_ARGUMENT,
           "lobe_pdf");
    EXPECT(lodestar_env_guide_update(env, cell, NULL, 1.0f, &outcome), LODESTAR_STATUS_NULL_ARGUMENT, "sample");
    EXPECT(lodestar_env_guide_update(env, cell, &sample, NAN, &outcome), LODESTAR_STATUS_NON_FINITE_ARGUMENT,
           "integrand");
    EXPECT(lodestar_env_guide_update(env, cell, &sample, -1.0f, &outcome), LODESTAR_STATUS_INVALID_ARGUMENT,
           "integrand");
    /* Only sky above arrives here (walls hide the rest): up gains on down. */
    for (int i = 0; i < 2000; ++i) {
        EXPECT_OK(lodestar_env_guide_sample(env, cell, (i * 0.618034f) - (int)(i * 0.618034f), (i % 40 + 0.5f) / 40,
                                            0.5f, &sample));
        float integrand = sample.direction.y > 0.5f ? 1.0f : 0.0f;
        EXPECT_OK(lodestar_env_guide_update(env, cell, &sample, integrand, &outcome));
    }
    EXPECT(lodestar_env_guide_rebuild(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT_OK(lodestar_env_guide_rebuild(env));
    float pdf_up = 0, pdf_down = 0;
    LodestarVec3 down = {0.1f, -0.9f, 0}, above = {-0.4f, 0.8f, 0.2f}; /* off the pole and the sun */
    EXPECT_OK(lodestar_env_guide_pdf(env, cell, above, &pdf_up));
    EXPECT_OK(lodestar_env_guide_pdf(env, cell, down, &pdf_down));
    TRUTH(pdf_up > 5 * pdf_down && pdf_down > 0);

    size_t size = 0, written = 0;
    EXPECT_OK(lodestar_env_guide_save(env, NULL, 0, &size));
    uint8_t *bytes = malloc(size);
    EXPECT(lodestar_env_guide_save(env, bytes, size - 1, &written), LODESTAR_STATUS_BUFFER_TOO_SMALL, "capacity");
    EXPECT_OK(lodestar_env_guide_save(env, bytes, size, &written));
    LodestarEnvGuide *loaded = NULL;
    bytes[size / 3] ^= 0x08;
    EXPECT(lodestar_env_guide_load(&config, bytes, size, luminance, W, H, &sun, &loaded),
           LODESTAR_STATUS_DECODE_FAILED, "checksum");
    bytes[size / 3] ^= 0x08;
    EXPECT(lodestar_env_guide_load(&config, bytes, size, luminance, W, H, NULL, &loaded),
           LODESTAR_STATUS_INVALID_ARGUMENT, "environment");
    luminance[0] = 2.0f; /* another map */
    EXPECT(lodestar_env_guide_load(&config, bytes, size, luminance, W, H, &sun, &loaded),
           LODESTAR_STATUS_INVALID_ARGUMENT, "environment");
    luminance[0] = 1.0f;
    TRUTH(loaded == NULL);
    EXPECT_OK(lodestar_env_guide_load(&config, bytes, size, luminance, W, H, &sun, &loaded));
    float loaded_up = 0;
    EXPECT_OK(lodestar_env_guide_pdf(loaded, cell, above, &loaded_up));
    TRUTH(loaded_up == pdf_up);
    EXPECT(lodestar_env_guide_merge(env, env), LODESTAR_STATUS_INVALID_ARGUMENT, "itself");
    EXPECT_OK(lodestar_env_guide_merge(loaded, env));
    EXPECT_OK(lodestar_env_guide_pdf(loaded, cell, above, &loaded_up));
    TRUTH(fabsf(loaded_up - pdf_up) <= 1e-5f * pdf_up);
    EXPECT_OK(lodestar_env_guide_reset(loaded));
    float reset_down = 0;
    EXPECT_OK(lodestar_env_guide_pdf(loaded, cell, down, &reset_down));
    TRUTH(reset_down > pdf_down); /* the sky below is no longer learned away */
    EXPECT_OK(lodestar_env_guide_release(loaded));
    free(bytes);
    EXPECT(lodestar_env_guide_release(NULL), LODESTAR_STATUS_NULL_ARGUMENT, "guide");
    EXPECT_OK(lodestar_env_guide_release(env));
}

int main(void) {
    TRUTH(lodestar_version() == LODESTAR_VERSION);
    config_errors();
    LodestarGuideConfig config;
    LodestarGuide *guide = NULL;
    EXPECT_OK(lodestar_guide_config_default(&config));
    config.region_count = 16;
    EXPECT_OK(lodestar_guide_create(&config, floor_positions, 4, floor_indices, 2, &guide));
    per_vertex_errors(guide);
    recorder_errors(guide);
    buffer_errors(guide);
    concurrent_updates(guide);
    EXPECT_OK(lodestar_guide_release(guide));
    bounded_structure_errors();
    light_guide_errors();
    env_guide_errors();
    printf("api_errors: %d of %d checks passed\n", checks - failures, checks);
    return failures == 0 ? 0 : 1;
}
