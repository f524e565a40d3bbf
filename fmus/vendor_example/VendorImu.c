/*
 * VendorImu: a strapdown IMU delivered as an FMI 2.0 co-simulation FMU, written in C
 * the way a sensor vendor ships one (its own variable names and units; see README.md).
 *
 * Per axis i, over a communication step [t, t + h], with the true increments d_i
 * (angle [rad], velocity [m/s]) given as inputs:
 *
 *     y_i = d_i + s_i d_i + b_i h + N sqrt(h) w_i,    w_i ~ N(0, 1) independent
 *
 *     s_i   scale-factor error            parameter in ppm
 *     b_i   bias                          gyro deg/h, accelerometer ug (micro standard gravity)
 *     N     white-noise density           gyro deg/sqrt(h), accelerometer ug/sqrt(Hz)
 *
 * computed in SI (rad, m/s) and published as
 *
 *     gyro_angle_i = y_i in deg           accel_dv_i = y_i in m/s
 *     gyro_rate_i  = y_i / h in deg/s     accel_f_i  = y_i / h in g (9.80665 m/s2)
 *
 * The outputs are zero at the start time (no increment yet). With noise_on = false
 * (or zero densities) the model is deterministic. The noise comes from xoshiro256**
 * seeded through splitmix64 from `seed`, turned into normal deviates with the polar
 * (Marsaglia) method; the generator restarts from `seed` at every initialisation, so a
 * reset and a new run with the same seed repeat the same outputs.
 *
 * FMI 2.0 support: co-simulation only, fixed or variable communication steps, reset,
 * debug logging by category; no FMU state get/set, no input interpolation, no output
 * derivatives, no asynchronous steps (the calls exist and report an error).
 */

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"

#ifndef VENDOR_IMU_GUID
#define VENDOR_IMU_GUID "{f828732d-9569-4347-a8ef-35f945a645b7}"
#endif

#define PI 3.14159265358979323846
#define RAD_PER_DEG (PI / 180.0)
#define DEG_PER_RAD (180.0 / PI)
#define RADPS_PER_DEGPH (PI / 180.0 / 3600.0)   /* 1 deg/h in rad/s */
#define RADRTS_PER_DEGRTH (PI / 180.0 / 60.0)   /* 1 deg/sqrt(h) in rad/sqrt(s) */
#define STANDARD_GRAVITY 9.80665                /* m/s2 */
#define MPS2_PER_UG (STANDARD_GRAVITY * 1e-6)   /* 1 ug in m/s2; 1 ug/sqrt(Hz) in m/s/sqrt(s) */
#define PER_PPM 1e-6

/* ------------------------------------------------------------ value references */
enum {
    VR_GYRO_BIAS = 0,      /* 0..2   deg/h        parameter */
    VR_GYRO_ARW = 3,       /* 3      deg/sqrt(h)  parameter */
    VR_GYRO_SF = 4,        /* 4..6   ppm          parameter */
    VR_ACCEL_BIAS = 7,     /* 7..9   ug           parameter */
    VR_ACCEL_VRW = 10,     /* 10     ug/sqrt(Hz)  parameter */
    VR_ACCEL_SF = 11,      /* 11..13 ppm          parameter */
    VR_TRUE_DTHETA = 20,   /* 20..22 rad          input */
    VR_TRUE_DV = 23,       /* 23..25 m/s          input */
    VR_GYRO_ANGLE = 30,    /* 30..32 deg          output */
    VR_ACCEL_DV = 33,      /* 33..35 m/s          output */
    VR_GYRO_RATE = 36,     /* 36..38 deg/s        output */
    VR_ACCEL_F = 39,       /* 39..41 g            output */
    N_REAL = 42,
    VR_SEED = 100,         /* Integer parameter */
    VR_NOISE_ON = 200,     /* Boolean parameter */
    VR_SERIAL = 300        /* String parameter */
};

enum { KIND_NONE = 0, KIND_PARAMETER, KIND_INPUT, KIND_OUTPUT };

static int real_kind(fmi2ValueReference vr) {
    if (vr <= 13) return KIND_PARAMETER;
    if (vr >= 20 && vr <= 25) return KIND_INPUT;
    if (vr >= 30 && vr <= 41) return KIND_OUTPUT;
    return KIND_NONE;
}

#define DEFAULT_SEED 1
#define DEFAULT_SERIAL "VI-2000-0001"

/* ------------------------------------------------------------------ instance */
typedef enum {
    STATE_INSTANTIATED = 1 << 0,
    STATE_INITIALIZATION = 1 << 1,
    STATE_STEP_COMPLETE = 1 << 2,
    STATE_STEP_FAILED = 1 << 3,
    STATE_TERMINATED = 1 << 4
} State;

#define ANY_STATE (STATE_INSTANTIATED | STATE_INITIALIZATION | STATE_STEP_COMPLETE | \
                   STATE_STEP_FAILED | STATE_TERMINATED)
/* values can be read once initialisation has begun */
#define READABLE (STATE_INITIALIZATION | STATE_STEP_COMPLETE | STATE_STEP_FAILED | \
                  STATE_TERMINATED)

enum { LOG_ERROR = 0, LOG_WARNING, LOG_CALLS, N_LOG_CATEGORIES };
static const char *const LOG_CATEGORY_NAMES[N_LOG_CATEGORIES] = {
    "logStatusError", "logStatusWarning", "logCalls"};

typedef struct {
    fmi2CallbackFunctions callbacks; /* a copy: the caller's struct may not outlive us */
    char *instance_name;
    State state;
    int log_on[N_LOG_CATEGORIES];

    double real[N_REAL];
    fmi2Integer seed;
    fmi2Boolean noise_on;
    char *serial;

    double time;       /* time of the last communication point [s] */
    uint64_t rng[4];   /* xoshiro256** state */
    int have_spare;    /* the polar method makes normal deviates in pairs */
    double spare;
} Instance;

/* ------------------------------------------------------------------- logging */
static void log_message(Instance *c, fmi2Status status, int category, const char *format,
                        ...) {
    char text[512], escaped[1024];
    size_t i, j;
    va_list args;
    if (c == NULL || c->callbacks.logger == NULL) return;
    if (!(status >= fmi2Error || c->log_on[category])) return;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    /* the logger takes a printf format: double every '%' of the finished text */
    for (i = 0, j = 0; text[i] != '\0' && j + 2 < sizeof escaped; i++) {
        escaped[j++] = text[i];
        if (text[i] == '%') escaped[j++] = '%';
    }
    escaped[j] = '\0';
    c->callbacks.logger(c->callbacks.componentEnvironment, c->instance_name, status,
                        LOG_CATEGORY_NAMES[category], escaped);
}

/* Check that `function` may be called in the current state; log an error if not. */
static int allowed(Instance *c, const char *function, int states) {
    if (c == NULL) return 0;
    if (!(c->state & states)) {
        log_message(c, fmi2Error, LOG_ERROR, "%s: not allowed in the current state (%d)",
                    function, (int)c->state);
        return 0;
    }
    log_message(c, fmi2OK, LOG_CALLS, "%s", function);
    return 1;
}

static char *copy_string(Instance *c, const char *text) {
    size_t n = strlen(text) + 1;
    char *copy = (char *)c->callbacks.allocateMemory(n, sizeof(char));
    if (copy != NULL) memcpy(copy, text, n);
    return copy;
}

/* ------------------------------------------------------------ random numbers */
static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

static uint64_t next_u64(Instance *c) {
    uint64_t *s = c->rng;
    uint64_t result = rotl(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

static void seed_rng(Instance *c, fmi2Integer seed) {
    uint64_t x = (uint64_t)(uint32_t)seed;
    int i;
    for (i = 0; i < 4; i++) c->rng[i] = splitmix64(&x);
    c->have_spare = 0;
}

/* uniform on (-1, 1): 53 random bits */
static double uniform_pm1(Instance *c) {
    return ((double)(next_u64(c) >> 11) * 0x1.0p-53) * 2.0 - 1.0;
}

static double normal(Instance *c) {
    double u, v, s, m;
    if (c->have_spare) {
        c->have_spare = 0;
        return c->spare;
    }
    do {
        u = uniform_pm1(c);
        v = uniform_pm1(c);
        s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    m = sqrt(-2.0 * log(s) / s);
    c->spare = v * m;
    c->have_spare = 1;
    return u * m;
}

/* -------------------------------------------------------------------- model */
static void set_start_values(Instance *c) {
    int i;
    for (i = 0; i < N_REAL; i++) c->real[i] = 0.0;
    c->seed = DEFAULT_SEED;
    c->noise_on = fmi2True;
    if (c->serial != NULL) c->callbacks.freeMemory(c->serial);
    c->serial = copy_string(c, DEFAULT_SERIAL);
    c->time = 0.0;
}

static void clear_outputs(Instance *c) {
    int i;
    for (i = VR_GYRO_ANGLE; i < N_REAL; i++) c->real[i] = 0.0;
}

/* One triad: true increments d[3] -> measured increments y[3] (SI). */
static void measure(Instance *c, const double *d, const double *bias, const double *sf_ppm,
                    double density, double h, double *y) {
    int i;
    for (i = 0; i < 3; i++) {
        double s = sf_ppm[i] * PER_PPM;
        y[i] = d[i] + s * d[i] + bias[i] * h;
        if (c->noise_on && density > 0.0) y[i] += density * sqrt(h) * normal(c);
    }
}

static void step(Instance *c, double h) {
    double gyro_bias[3], accel_bias[3], y_gyro[3], y_accel[3];
    int i;
    for (i = 0; i < 3; i++) {
        gyro_bias[i] = c->real[VR_GYRO_BIAS + i] * RADPS_PER_DEGPH;
        accel_bias[i] = c->real[VR_ACCEL_BIAS + i] * MPS2_PER_UG;
    }
    /* gyro first, then accelerometer: the order of the noise draws is part of the model */
    measure(c, &c->real[VR_TRUE_DTHETA], gyro_bias, &c->real[VR_GYRO_SF],
            c->real[VR_GYRO_ARW] * RADRTS_PER_DEGRTH, h, y_gyro);
    measure(c, &c->real[VR_TRUE_DV], accel_bias, &c->real[VR_ACCEL_SF],
            c->real[VR_ACCEL_VRW] * MPS2_PER_UG, h, y_accel);
    for (i = 0; i < 3; i++) {
        c->real[VR_GYRO_ANGLE + i] = y_gyro[i] * DEG_PER_RAD;
        c->real[VR_ACCEL_DV + i] = y_accel[i];
        c->real[VR_GYRO_RATE + i] = y_gyro[i] * DEG_PER_RAD / h;
        c->real[VR_ACCEL_F + i] = y_accel[i] / h / STANDARD_GRAVITY;
    }
}

static int check_parameters(Instance *c) {
    if (c->real[VR_GYRO_ARW] < 0.0 || c->real[VR_ACCEL_VRW] < 0.0) {
        log_message(c, fmi2Error, LOG_ERROR,
                    "noise densities must be >= 0, got gyro_arw = %g, accel_vrw = %g",
                    c->real[VR_GYRO_ARW], c->real[VR_ACCEL_VRW]);
        return 0;
    }
    return 1;
}

/* ============================================================ FMI 2.0 API */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component component, fmi2Boolean loggingOn,
                               size_t nCategories, const fmi2String categories[]) {
    Instance *c = (Instance *)component;
    size_t i;
    int k;
    if (c == NULL) return fmi2Error;
    if (nCategories == 0) {
        for (k = 0; k < N_LOG_CATEGORIES; k++) c->log_on[k] = loggingOn ? 1 : 0;
        return fmi2OK;
    }
    for (i = 0; i < nCategories; i++) {
        int found = 0;
        for (k = 0; k < N_LOG_CATEGORIES; k++) {
            if (categories[i] != NULL && strcmp(categories[i], LOG_CATEGORY_NAMES[k]) == 0) {
                c->log_on[k] = loggingOn ? 1 : 0;
                found = 1;
            }
        }
        if (!found) {
            log_message(c, fmi2Error, LOG_ERROR,
                        "fmi2SetDebugLogging: unknown log category '%s'",
                        categories[i] != NULL ? categories[i] : "(null)");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    Instance *c;
    const char *name = instanceName != NULL ? instanceName : "";
    int k;
    (void)fmuResourceLocation;
    (void)visible;
    if (functions == NULL || functions->allocateMemory == NULL ||
        functions->freeMemory == NULL) {
        if (functions != NULL && functions->logger != NULL)
            functions->logger(functions->componentEnvironment, name, fmi2Error,
                              "logStatusError",
                              "fmi2Instantiate: allocateMemory and freeMemory are required");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        if (functions->logger != NULL)
            functions->logger(functions->componentEnvironment, name, fmi2Error,
                              "logStatusError",
                              "fmi2Instantiate: VendorImu implements Co-Simulation only");
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, VENDOR_IMU_GUID) != 0) {
        if (functions->logger != NULL)
            functions->logger(functions->componentEnvironment, name, fmi2Error,
                              "logStatusError",
                              "fmi2Instantiate: wrong GUID (expected " VENDOR_IMU_GUID ")");
        return NULL;
    }
    c = (Instance *)functions->allocateMemory(1, sizeof(Instance));
    if (c == NULL) return NULL;
    memset(c, 0, sizeof *c);
    c->callbacks = *functions;
    c->instance_name = copy_string(c, name);
    for (k = 0; k < N_LOG_CATEGORIES; k++) c->log_on[k] = loggingOn ? 1 : 0;
    c->log_on[LOG_CALLS] = 0; /* call tracing only on request (fmi2SetDebugLogging) */
    set_start_values(c);
    if (c->instance_name == NULL || c->serial == NULL) {
        if (c->instance_name != NULL) functions->freeMemory(c->instance_name);
        if (c->serial != NULL) functions->freeMemory(c->serial);
        functions->freeMemory(c);
        return NULL;
    }
    c->state = STATE_INSTANTIATED;
    log_message(c, fmi2OK, LOG_CALLS, "fmi2Instantiate: %s", DEFAULT_SERIAL);
    return c;
}

void fmi2FreeInstance(fmi2Component component) {
    Instance *c = (Instance *)component;
    fmi2CallbackFreeMemory release;
    if (c == NULL) return;
    log_message(c, fmi2OK, LOG_CALLS, "fmi2FreeInstance");
    release = c->callbacks.freeMemory;
    if (c->serial != NULL) release(c->serial);
    if (c->instance_name != NULL) release(c->instance_name);
    release(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component component, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *c = (Instance *)component;
    (void)toleranceDefined;
    (void)tolerance;
    if (!allowed(c, "fmi2SetupExperiment", STATE_INSTANTIATED)) return fmi2Error;
    if (stopTimeDefined && stopTime < startTime) {
        log_message(c, fmi2Error, LOG_ERROR,
                    "fmi2SetupExperiment: stop time %g is before start time %g", stopTime,
                    startTime);
        return fmi2Error;
    }
    c->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component component) {
    Instance *c = (Instance *)component;
    if (!allowed(c, "fmi2EnterInitializationMode", STATE_INSTANTIATED)) return fmi2Error;
    c->state = STATE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component component) {
    Instance *c = (Instance *)component;
    if (!allowed(c, "fmi2ExitInitializationMode", STATE_INITIALIZATION)) return fmi2Error;
    if (!check_parameters(c)) return fmi2Error;
    seed_rng(c, c->seed);
    clear_outputs(c);
    log_message(c, fmi2OK, LOG_CALLS, "initialised %s with seed %d", c->serial, (int)c->seed);
    c->state = STATE_STEP_COMPLETE;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component component) {
    Instance *c = (Instance *)component;
    if (!allowed(c, "fmi2Terminate", STATE_STEP_COMPLETE | STATE_STEP_FAILED))
        return fmi2Error;
    c->state = STATE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component component) {
    Instance *c = (Instance *)component;
    if (!allowed(c, "fmi2Reset", ANY_STATE)) return fmi2Error;
    set_start_values(c);
    if (c->serial == NULL) return fmi2Fatal;
    c->state = STATE_INSTANTIATED;
    return fmi2OK;
}

/* ------------------------------------------------------------ get and set */
fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    Instance *c = (Instance *)component;
    size_t i;
    if (!allowed(c, "fmi2GetReal", READABLE)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= N_REAL || real_kind(vr[i]) == KIND_NONE) {
            log_message(c, fmi2Error, LOG_ERROR, "fmi2GetReal: no Real variable with value "
                        "reference %u", (unsigned)vr[i]);
            return fmi2Error;
        }
        value[i] = c->real[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    Instance *c = (Instance *)component;
    size_t i;
    if (!allowed(c, "fmi2GetInteger", READABLE)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (vr[i] != VR_SEED) {
            log_message(c, fmi2Error, LOG_ERROR, "fmi2GetInteger: no Integer variable with "
                        "value reference %u", (unsigned)vr[i]);
            return fmi2Error;
        }
        value[i] = c->seed;
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    Instance *c = (Instance *)component;
    size_t i;
    if (!allowed(c, "fmi2GetBoolean", READABLE)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (vr[i] != VR_NOISE_ON) {
            log_message(c, fmi2Error, LOG_ERROR, "fmi2GetBoolean: no Boolean variable with "
                        "value reference %u", (unsigned)vr[i]);
            return fmi2Error;
        }
        value[i] = c->noise_on;
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    Instance *c = (Instance *)component;
    size_t i;
    if (!allowed(c, "fmi2GetString", READABLE)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (vr[i] != VR_SERIAL) {
            log_message(c, fmi2Error, LOG_ERROR, "fmi2GetString: no String variable with "
                        "value reference %u", (unsigned)vr[i]);
            return fmi2Error;
        }
        value[i] = c->serial;
    }
    return fmi2OK;
}

/* Parameters (variability fixed) are set before initialisation ends; inputs any time. */
#define BEFORE_STEPPING (STATE_INSTANTIATED | STATE_INITIALIZATION)

fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    Instance *c = (Instance *)component;
    size_t i;
    if (!allowed(c, "fmi2SetReal", BEFORE_STEPPING | STATE_STEP_COMPLETE)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        int kind = vr[i] < N_REAL ? real_kind(vr[i]) : KIND_NONE;
        if (kind == KIND_NONE || kind == KIND_OUTPUT) {
            log_message(c, fmi2Error, LOG_ERROR, "fmi2SetReal: value reference %u is not a "
                        "parameter or an input", (unsigned)vr[i]);
            return fmi2Error;
        }
        if (kind == KIND_PARAMETER && !(c->state & BEFORE_STEPPING)) {
            log_message(c, fmi2Error, LOG_ERROR, "fmi2SetReal: parameter %u is fixed after "
                        "initialisation", (unsigned)vr[i]);
            return fmi2Error;
        }
        if (!isfinite(value[i])) {
            log_message(c, fmi2Error, LOG_ERROR, "fmi2SetReal: value reference %u: expected "
                        "a finite value, got %g", (unsigned)vr[i], value[i]);
            return fmi2Error;
        }
        c->real[vr[i]] = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    Instance *c = (Instance *)component;
    size_t i;
    if (!allowed(c, "fmi2SetInteger", BEFORE_STEPPING)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (vr[i] != VR_SEED) {
            log_message(c, fmi2Error, LOG_ERROR, "fmi2SetInteger: no Integer parameter with "
                        "value reference %u", (unsigned)vr[i]);
            return fmi2Error;
        }
        c->seed = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    Instance *c = (Instance *)component;
    size_t i;
    if (!allowed(c, "fmi2SetBoolean", BEFORE_STEPPING)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (vr[i] != VR_NOISE_ON) {
            log_message(c, fmi2Error, LOG_ERROR, "fmi2SetBoolean: no Boolean parameter with "
                        "value reference %u", (unsigned)vr[i]);
            return fmi2Error;
        }
        c->noise_on = value[i] ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    Instance *c = (Instance *)component;
    size_t i;
    if (!allowed(c, "fmi2SetString", BEFORE_STEPPING)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        char *copy;
        if (vr[i] != VR_SERIAL || value[i] == NULL) {
            log_message(c, fmi2Error, LOG_ERROR, "fmi2SetString: no String parameter with "
                        "value reference %u (or a NULL value)", (unsigned)vr[i]);
            return fmi2Error;
        }
        copy = copy_string(c, value[i]);
        if (copy == NULL) return fmi2Fatal;
        c->callbacks.freeMemory(c->serial);
        c->serial = copy;
    }
    return fmi2OK;
}

/* ------------------------------------------------------------- co-simulation */
fmi2Status fmi2DoStep(fmi2Component component, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentCommunicationPoint) {
    Instance *c = (Instance *)component;
    double h = communicationStepSize, t = currentCommunicationPoint;
    (void)noSetFMUStatePriorToCurrentCommunicationPoint;
    if (!allowed(c, "fmi2DoStep", STATE_STEP_COMPLETE)) return fmi2Error;
    if (!(h > 0.0) || !isfinite(h)) {
        log_message(c, fmi2Error, LOG_ERROR, "fmi2DoStep: expected a step size > 0, got %g", h);
        return fmi2Error;
    }
    if (fabs(t - c->time) > 1e-9 * (fabs(t) > 1.0 ? fabs(t) : 1.0)) {
        log_message(c, fmi2Error, LOG_ERROR,
                    "fmi2DoStep: expected the step to start at t = %.17g s, got %.17g s",
                    c->time, t);
        return fmi2Error;
    }
    step(c, h);
    c->time = t + h;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component component) {
    Instance *c = (Instance *)component;
    log_message(c, fmi2Error, LOG_ERROR, "fmi2CancelStep: steps are never asynchronous");
    return fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component component, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    Instance *c = (Instance *)component;
    (void)vr, (void)nvr, (void)order, (void)value;
    log_message(c, fmi2Error, LOG_ERROR,
                "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs = false)");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component component, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    Instance *c = (Instance *)component;
    (void)vr, (void)nvr, (void)order, (void)value;
    log_message(c, fmi2Error, LOG_ERROR,
                "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder = 0)");
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component component, const fmi2StatusKind s, fmi2Status *value) {
    Instance *c = (Instance *)component;
    (void)s, (void)value;
    log_message(c, fmi2Error, LOG_ERROR, "fmi2GetStatus: no asynchronous step to report on");
    return fmi2Error;
}

fmi2Status fmi2GetRealStatus(fmi2Component component, const fmi2StatusKind s,
                             fmi2Real *value) {
    Instance *c = (Instance *)component;
    if (c == NULL) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) {
        *value = c->time;
        return fmi2OK;
    }
    log_message(c, fmi2Error, LOG_ERROR, "fmi2GetRealStatus: status kind %d not available",
                (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component component, const fmi2StatusKind s,
                                fmi2Integer *value) {
    Instance *c = (Instance *)component;
    (void)value;
    log_message(c, fmi2Error, LOG_ERROR, "fmi2GetIntegerStatus: status kind %d not available",
                (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component component, const fmi2StatusKind s,
                                fmi2Boolean *value) {
    Instance *c = (Instance *)component;
    if (c == NULL) return fmi2Error;
    if (s == fmi2Terminated) {
        *value = fmi2False; /* the model never asks to stop */
        return fmi2OK;
    }
    log_message(c, fmi2Error, LOG_ERROR, "fmi2GetBooleanStatus: status kind %d not available",
                (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetStringStatus(fmi2Component component, const fmi2StatusKind s,
                               fmi2String *value) {
    Instance *c = (Instance *)component;
    (void)value;
    log_message(c, fmi2Error, LOG_ERROR, "fmi2GetStringStatus: status kind %d not available",
                (int)s);
    return fmi2Error;
}

/* ------------------------------------------- FMU state, derivatives: not provided */
static fmi2Status not_supported(fmi2Component component, const char *function) {
    log_message((Instance *)component, fmi2Error, LOG_ERROR,
                "%s: not supported by VendorImu (see its model description)", function);
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)state;
    return not_supported(c, "fmi2GetFMUstate");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    (void)state;
    return not_supported(c, "fmi2SetFMUstate");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)state;
    return not_supported(c, "fmi2FreeFMUstate");
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)state, (void)size;
    return not_supported(c, "fmi2SerializedFMUstateSize");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[],
                                 size_t size) {
    (void)state, (void)bytes, (void)size;
    return not_supported(c, "fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                   fmi2FMUstate *state) {
    (void)bytes, (void)size, (void)state;
    return not_supported(c, "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[],
                                        size_t nUnknown, const fmi2ValueReference known[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)unknown, (void)nUnknown, (void)known, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    return not_supported(c, "fmi2GetDirectionalDerivative");
}
