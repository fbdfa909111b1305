/* FMI 2.0 co-simulation interface of the pneumafit plant FMU.
 *
 * Inputs u_P, u_N (V) are held over a communication step, or follow the
 * first derivative a master gives with fmi2SetRealInputDerivatives
 * (canInterpolateInputs). Each step is cut into equal Runge-Kutta steps no
 * longer than the parameter integration_step, and enough that a command
 * changes by at most PF_COMMAND_RESOLUTION within one (as the simulator's
 * substeps). Parameters (value references PF_VR_PARAMETER_BASE + layout
 * index) and the start values of the states can be set until
 * fmi2ExitInitializationMode; they are fixed afterwards.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>

#include "fmi2Functions.h"
#include "pneumafit_model.h"
#include "pneumafit_values.h"

enum { PHASE_INSTANTIATED, PHASE_INITIALIZATION, PHASE_STEPPING, PHASE_TERMINATED,
       PHASE_FAILED };

typedef struct {
    /* everything an FMU state snapshot holds */
    pf_model model;
    pf_state state;
    double x0[PF_NX]; /* start values (NaN: the simulator's default) */
    double u_p, u_n, du_p, du_n;
    double h_max;
    double time;
    int phase;
} pf_data;

typedef struct {
    pf_data d;
    double aux[PF_NAUX];
    int aux_valid;
    char *name;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging;
} pf_instance;

static void log_msg(pf_instance *c, fmi2Status status, const char *category, const char *fmt,
                    ...)
{
    char buf[512];
    va_list ap;
    if (c == NULL || c->logger == NULL) return;
    if (!c->logging && status < fmi2Error) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof(buf), fmt, ap);
    va_end(ap);
    c->logger(c->env, c->name, status, category, "%s", buf);
}

static void set_defaults(pf_data *d)
{
    int i;
    memset(d, 0, sizeof(*d));
    d->model.heat = PF_HEAT;
    d->model.lugre = PF_LUGRE;
    d->model.sutherland = PF_SUTHERLAND;
    d->model.valve_map = PF_VALVE_MAP;
    d->model.chamber_leak = PF_EFFECT_CHAMBER_LEAKAGE;
    d->model.external_leak = PF_EFFECT_EXTERNAL_LEAKAGE;
    d->model.valve_order = PF_EFFECT_VALVE_DYNAMICS;
    d->model.wall_mass = PF_EFFECT_WALL_THERMAL_MASS;
    d->model.forced_conv = PF_EFFECT_FORCED_CONVECTION;
    d->model.supply_drop = PF_EFFECT_SUPPLY_PRESSURE_DROP;
    d->model.seal = PF_EFFECT_SEAL_FRICTION;
    d->model.asym = PF_EFFECT_FRICTION_ASYMMETRY;
    d->model.area = PF_EFFECT_EFFECTIVE_AREA;
    for (i = 0; i < PF_NP; i++) d->model.p[i] = PF_PARAMETER_VALUES[i];
    for (i = 0; i < PF_NX; i++) d->x0[i] = NAN;
    pf_start_defaults(d->x0);
    d->h_max = PF_INTEGRATION_STEP;
    d->phase = PHASE_INSTANTIATED;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    (void)nCategories;
    (void)categories;
    if (c == NULL) return fmi2Error;
    ((pf_instance *)c)->logging = loggingOn ? 1 : 0;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    pf_instance *c;
    const char *name = instanceName ? instanceName : "pneumafit";
    (void)fmuResourceLocation;
    (void)visible;
    if (fmuType != fmi2CoSimulation) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                              "this FMU supports co-simulation only");
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, PF_GUID) != 0) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                              "GUID %s does not match this FMU's %s", fmuGUID ? fmuGUID : "(null)",
                              PF_GUID);
        return NULL;
    }
    c = (pf_instance *)calloc(1, sizeof(pf_instance));
    if (c == NULL) return NULL;
    c->name = (char *)malloc(strlen(name) + 1);
    if (c->name == NULL) {
        free(c);
        return NULL;
    }
    strcpy(c->name, name);
    c->logger = functions ? functions->logger : NULL;
    c->env = functions ? functions->componentEnvironment : NULL;
    c->logging = loggingOn ? 1 : 0;
    set_defaults(&c->d);
    return c;
}

void fmi2FreeInstance(fmi2Component c)
{
    pf_instance *inst = (pf_instance *)c;
    if (inst == NULL) return;
    free(inst->name);
    free(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    pf_instance *inst = (pf_instance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (inst == NULL) return fmi2Error;
    inst->d.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    pf_instance *inst = (pf_instance *)c;
    if (inst == NULL) return fmi2Error;
    inst->d.phase = PHASE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    pf_instance *inst = (pf_instance *)c;
    pf_inputs in;
    if (inst == NULL) return fmi2Error;
    if (!pf_admissible(&inst->d.model)) {
        log_msg(inst, fmi2Error, "logStatusError",
                "the parameters are not physically admissible (see pneumafit's "
                "kernel.admissible: e.g. rod < bore, static >= Coulomb friction, "
                "valve_time_constant > 0 for a first-order valve)");
        inst->d.phase = PHASE_FAILED;
        return fmi2Error;
    }
    if (!(inst->d.h_max > 0.0) || !isfinite(inst->d.h_max)) {
        log_msg(inst, fmi2Error, "logStatusError",
                "integration_step: expected a positive step in s, found %g", inst->d.h_max);
        inst->d.phase = PHASE_FAILED;
        return fmi2Error;
    }
    pf_derive(&inst->d.model);
    in.u_p0 = inst->d.u_p;
    in.u_n0 = inst->d.u_n;
    in.du_p = 0.0;
    in.du_n = 0.0;
    pf_initial_state(&inst->d.model, inst->d.x0, &in, &inst->d.state);
    inst->aux_valid = 0;
    inst->d.phase = PHASE_STEPPING;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    pf_instance *inst = (pf_instance *)c;
    if (inst == NULL) return fmi2Error;
    inst->d.phase = PHASE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    pf_instance *inst = (pf_instance *)c;
    if (inst == NULL) return fmi2Error;
    set_defaults(&inst->d);
    inst->aux_valid = 0;
    return fmi2OK;
}

/* ------------------------------------------------------------ get/set */

static int is_parameter(fmi2ValueReference vr)
{
    return vr >= PF_VR_PARAMETER_BASE && vr < PF_VR_PARAMETER_BASE + PF_NP;
}

static int start_index(fmi2ValueReference vr)
{
    if (vr >= PF_VR_START_BASE && vr < PF_VR_START_BASE + PF_NX &&
        pf_is_start_variable((int)(vr - PF_VR_START_BASE)))
        return (int)(vr - PF_VR_START_BASE);
    return -1;
}

static void update_aux(pf_instance *inst)
{
    double dx[PF_NX];
    if (inst->aux_valid) return;
    if (inst->d.phase == PHASE_STEPPING || inst->d.phase == PHASE_TERMINATED) {
        pf_rhs(&inst->d.model, inst->d.state.x, inst->d.state.mode, inst->d.u_p, inst->d.u_n, dx,
               inst->aux);
    } else {
        memset(inst->aux, 0, sizeof(inst->aux));
    }
    inst->aux_valid = 1;
}

static int output_value(pf_instance *inst, fmi2ValueReference vr, double *value)
{
    const double *x = inst->d.state.x;
    int started = inst->d.phase == PHASE_STEPPING || inst->d.phase == PHASE_TERMINATED;
    int state_index = -1;
    switch (vr) {
    case PF_VR_y: state_index = PF_X_y; break;
    case PF_VR_v: state_index = PF_X_v; break;
    case PF_VR_p_N: state_index = PF_X_p_N; break;
    case PF_VR_p_P: state_index = PF_X_p_P; break;
    case PF_VR_T_N: state_index = PF_X_T_N; break;
    case PF_VR_T_P: state_index = PF_X_T_P; break;
    case PF_VR_m_supply: state_index = PF_X_m_supply; break;
    case PF_VR_m_exhaust: state_index = PF_X_m_exhaust; break;
    case PF_VR_z_f: state_index = PF_X_z_f; break;
    case PF_VR_Tw_N: state_index = PF_X_Tw_N; break;
    case PF_VR_Tw_P: state_index = PF_X_Tw_P; break;
    case PF_VR_us_N: state_index = PF_X_us_N; break;
    case PF_VR_us_P: state_index = PF_X_us_P; break;
    case PF_VR_qm_N: update_aux(inst); *value = inst->aux[PF_A_QN]; return 1;
    case PF_VR_qm_P: update_aux(inst); *value = inst->aux[PF_A_QP]; return 1;
    case PF_VR_lambda_N: update_aux(inst); *value = inst->aux[PF_A_LAMN]; return 1;
    case PF_VR_lambda_P: update_aux(inst); *value = inst->aux[PF_A_LAMP]; return 1;
    case PF_VR_F_f: update_aux(inst); *value = inst->aux[PF_A_FF]; return 1;
    default: return 0;
    }
    if (started) {
        *value = x[state_index];
    } else {
        /* before initialization: the start value, or the default the model takes */
        double v = inst->d.x0[state_index];
        if (!isfinite(v)) {
            if (state_index == PF_X_p_N || state_index == PF_X_p_P)
                v = inst->d.model.p[PF_P_exhaust_pressure];
            else if (state_index == PF_X_T_N || state_index == PF_X_T_P ||
                     state_index == PF_X_Tw_N || state_index == PF_X_Tw_P)
                v = inst->d.model.p[PF_P_wall_temperature];
            else
                v = 0.0;
        }
        *value = v;
    }
    return 1;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    pf_instance *inst = (pf_instance *)c;
    size_t i;
    int k;
    if (inst == NULL) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (is_parameter(vr[i])) {
            value[i] = inst->d.model.p[vr[i] - PF_VR_PARAMETER_BASE];
        } else if ((k = start_index(vr[i])) >= 0) {
            value[i] = inst->d.x0[k];
        } else if (vr[i] == PF_VR_INTEGRATION_STEP) {
            value[i] = inst->d.h_max;
        } else if (vr[i] == PF_VR_u_P) {
            value[i] = inst->d.u_p;
        } else if (vr[i] == PF_VR_u_N) {
            value[i] = inst->d.u_n;
        } else if (!output_value(inst, vr[i], &value[i])) {
            log_msg(inst, fmi2Error, "logStatusError", "fmi2GetReal: unknown value reference %u",
                    vr[i]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    pf_instance *inst = (pf_instance *)c;
    size_t i;
    int k, fixed;
    if (inst == NULL) return fmi2Error;
    fixed = inst->d.phase != PHASE_INSTANTIATED && inst->d.phase != PHASE_INITIALIZATION;
    for (i = 0; i < nvr; i++) {
        if (vr[i] == PF_VR_u_P) {
            inst->d.u_p = value[i];
            inst->d.du_p = 0.0;
            inst->aux_valid = 0;
            continue;
        }
        if (vr[i] == PF_VR_u_N) {
            inst->d.u_n = value[i];
            inst->d.du_n = 0.0;
            inst->aux_valid = 0;
            continue;
        }
        k = start_index(vr[i]);
        if (k < 0 && !is_parameter(vr[i]) && vr[i] != PF_VR_INTEGRATION_STEP) {
            log_msg(inst, fmi2Error, "logStatusError",
                    "fmi2SetReal: value reference %u is not an input or a parameter", vr[i]);
            return fmi2Error;
        }
        if (fixed) {
            log_msg(inst, fmi2Error, "logStatusError",
                    "fmi2SetReal: value reference %u is a fixed parameter or start value; set "
                    "it before fmi2ExitInitializationMode",
                    vr[i]);
            return fmi2Error;
        }
        if (k >= 0)
            inst->d.x0[k] = value[i];
        else if (vr[i] == PF_VR_INTEGRATION_STEP)
            inst->d.h_max = value[i];
        else
            inst->d.model.p[vr[i] - PF_VR_PARAMETER_BASE] = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    pf_instance *inst = (pf_instance *)c;
    size_t i;
    if (inst == NULL) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (order[i] != 1) {
            log_msg(inst, fmi2Error, "logStatusError",
                    "fmi2SetRealInputDerivatives: only first derivatives are supported, found "
                    "order %d",
                    order[i]);
            return fmi2Error;
        }
        if (vr[i] == PF_VR_u_P)
            inst->d.du_p = value[i];
        else if (vr[i] == PF_VR_u_N)
            inst->d.du_n = value[i];
        else {
            log_msg(inst, fmi2Error, "logStatusError",
                    "fmi2SetRealInputDerivatives: value reference %u is not an input", vr[i]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[], fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    log_msg((pf_instance *)c, fmi2Error, "logStatusError",
            "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder = 0)");
    return fmi2Error;
}

static fmi2Status no_variables(fmi2Component c, const char *what, size_t nvr)
{
    if (nvr == 0) return fmi2OK;
    log_msg((pf_instance *)c, fmi2Error, "logStatusError", "%s: this FMU has no such variables",
            what);
    return fmi2Error;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[])
{
    (void)vr;
    (void)value;
    return no_variables(c, "fmi2GetInteger", nvr);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[])
{
    (void)vr;
    (void)value;
    return no_variables(c, "fmi2GetBoolean", nvr);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[])
{
    (void)vr;
    (void)value;
    return no_variables(c, "fmi2GetString", nvr);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    (void)vr;
    (void)value;
    return no_variables(c, "fmi2SetInteger", nvr);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[])
{
    (void)vr;
    (void)value;
    return no_variables(c, "fmi2SetBoolean", nvr);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[])
{
    (void)vr;
    (void)value;
    return no_variables(c, "fmi2SetString", nvr);
}

/* ---------------------------------------------------------- FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    pf_instance *inst = (pf_instance *)c;
    pf_data *snap;
    if (inst == NULL || state == NULL) return fmi2Error;
    snap = (pf_data *)(*state ? *state : malloc(sizeof(pf_data)));
    if (snap == NULL) return fmi2Error;
    *snap = inst->d;
    *state = snap;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    pf_instance *inst = (pf_instance *)c;
    if (inst == NULL || state == NULL) return fmi2Error;
    inst->d = *(pf_data *)state;
    inst->aux_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    (void)c;
    if (state == NULL) return fmi2OK;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    (void)c;
    (void)state;
    *size = sizeof(pf_data);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte serialized[],
                                 size_t size)
{
    if (state == NULL || size != sizeof(pf_data)) {
        log_msg((pf_instance *)c, fmi2Error, "logStatusError",
                "fmi2SerializeFMUstate: expected a state and %zu bytes", sizeof(pf_data));
        return fmi2Error;
    }
    memcpy(serialized, state, sizeof(pf_data));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serialized[], size_t size,
                                   fmi2FMUstate *state)
{
    pf_data *snap;
    if (size != sizeof(pf_data) || state == NULL) {
        log_msg((pf_instance *)c, fmi2Error, "logStatusError",
                "fmi2DeSerializeFMUstate: expected %zu bytes of this FMU's state, found %zu",
                sizeof(pf_data), size);
        return fmi2Error;
    }
    snap = (pf_data *)(*state ? *state : malloc(sizeof(pf_data)));
    if (snap == NULL) return fmi2Error;
    memcpy(snap, serialized, sizeof(pf_data));
    *state = snap;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[])
{
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    log_msg((pf_instance *)c, fmi2Error, "logStatusError",
            "fmi2GetDirectionalDerivative: not supported");
    return fmi2Error;
}

/* --------------------------------------------------------------- step */

static const char *status_message(int status)
{
    switch (status) {
    case PF_NONFINITE: return "the state became non-finite (NaN or inf)";
    case PF_NONPHYSICAL: return "a pressure or temperature fell to zero or below";
    default: return "the simulation failed";
    }
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    pf_instance *inst = (pf_instance *)c;
    pf_inputs in;
    int status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (inst == NULL) return fmi2Error;
    if (inst->d.phase != PHASE_STEPPING) {
        log_msg(inst, fmi2Error, "logStatusError",
                inst->d.phase == PHASE_FAILED
                    ? "fmi2DoStep: an earlier step failed; reset or instantiate the FMU again"
                    : "fmi2DoStep: expected the FMU to be initialized (step mode)");
        return fmi2Error;
    }
    if (!(communicationStepSize > 0.0)) {
        log_msg(inst, fmi2Error, "logStatusError",
                "fmi2DoStep: expected a positive communication step, found %g",
                communicationStepSize);
        return fmi2Error;
    }
    in.u_p0 = inst->d.u_p;
    in.u_n0 = inst->d.u_n;
    in.du_p = inst->d.du_p * communicationStepSize;
    in.du_n = inst->d.du_n * communicationStepSize;
    status = pf_advance(&inst->d.model, &inst->d.state, &in, communicationStepSize,
                        inst->d.h_max);
    inst->aux_valid = 0;
    if (status != PF_OK) {
        inst->d.phase = PHASE_FAILED;
        log_msg(inst, fmi2Error, "logStatusError", "fmi2DoStep from t = %.9g s: %s",
                currentCommunicationPoint, status_message(status));
        return fmi2Error;
    }
    inst->d.time = currentCommunicationPoint + communicationStepSize;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    log_msg((pf_instance *)c, fmi2Error, "logStatusError",
            "fmi2CancelStep: doStep never returns fmi2Pending here");
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    pf_instance *inst = (pf_instance *)c;
    if (inst == NULL || s != fmi2DoStepStatus) return fmi2Discard;
    *value = inst->d.phase == PHASE_FAILED ? fmi2Error : fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    pf_instance *inst = (pf_instance *)c;
    if (inst == NULL || s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = inst->d.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    pf_instance *inst = (pf_instance *)c;
    if (inst == NULL || s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}
