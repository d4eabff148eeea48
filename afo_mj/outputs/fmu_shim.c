/* afo_mj FMI 2.0 co-simulation shim (compiled by `afo-mj export-fmu`, see
 * afo_mj/outputs/fmu_export.py).
 *
 * Every FMI 2.0 function forwards to the Python module afo_mj.outputs.fmu_runtime, which
 * steps the circuit with the same compiled kernel a native replay uses
 * (afo_mj.circuits.device.CircuitDevice.run_imposed). This file holds no model: it finds the
 * Python interpreter, takes its global interpreter lock around each call, passes value
 * references and values as addresses, and hands the runtime's messages to the host's logger.
 *
 * The Python C API is looked up at run time (dlsym), so the library links against no
 * libpython: inside a Python host (FMPy) it uses the interpreter already running; in any
 * other host it loads the libpython recorded at export (AFO_MJ_LIBPYTHON) and starts it.
 * No Python header is needed to compile it; define AFO_MJ_STANDARD_HEADERS and put the
 * standard fmi2Functions.h on the include path to check the signatures against it.
 */
#include <dlfcn.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef AFO_MJ_STANDARD_HEADERS
#include "fmi2Functions.h"
#else
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
#define fmi2True 1
#define fmi2False 0
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum {
    fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated
} fmi2StatusKind;
typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status,
                                   fmi2String, fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);
typedef struct {
    const fmi2CallbackLogger logger;
    const fmi2CallbackAllocateMemory allocateMemory;
    const fmi2CallbackFreeMemory freeMemory;
    const fmi2StepFinished stepFinished;
    const fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;
#define FMI2_Export __attribute__((visibility("default")))
#endif

#ifndef AFO_MJ_LIBPYTHON
#define AFO_MJ_LIBPYTHON "libpython3.so"
#endif

/* ---- the Python C API, by address ------------------------------------------------------ */
typedef void PyObj;
static struct {
    int ready;
    int (*IsInitialized)(void);
    void (*InitializeEx)(int);
    int (*GILState_Ensure)(void);
    void (*GILState_Release)(int);
    void *(*Eval_SaveThread)(void);
    PyObj *(*Import_ImportModule)(const char *);
    PyObj *(*Object_CallMethod)(PyObj *, const char *, const char *, ...);
    long long (*Long_AsLongLong)(PyObj *);
    void (*DecRef)(PyObj *);
    PyObj *(*Err_Occurred)(void);
    void (*Err_Fetch)(PyObj **, PyObj **, PyObj **);
    void (*Err_Clear)(void);
    PyObj *(*Object_Str)(PyObj *);
    const char *(*Unicode_AsUTF8)(PyObj *);
    PyObj *(*Sys_GetObject)(const char *);
    int (*List_Insert)(PyObj *, ptrdiff_t, PyObj *);
    PyObj *(*Unicode_FromString)(const char *);
} py;

static PyObj *runtime = NULL;     /* afo_mj.outputs.fmu_runtime (a strong reference) */
static char load_error[1024];

static int bind_python(void) {
    void *lib = RTLD_DEFAULT;
    if (py.ready) return 1;
    if (dlsym(RTLD_DEFAULT, "Py_IsInitialized") == NULL) {
        /* not a Python host: load the interpreter the FMU was exported with */
        lib = dlopen(AFO_MJ_LIBPYTHON, RTLD_NOW | RTLD_GLOBAL);
        if (lib == NULL) {
            snprintf(load_error, sizeof load_error,
                     "cannot load the Python library %s: %s (the host needs the Python "
                     "afo_mj runs in)", AFO_MJ_LIBPYTHON, dlerror());
            return 0;
        }
    }
#define BIND(field, name)                                                            \
    *(void **)(&py.field) = dlsym(lib, name);                                        \
    if (py.field == NULL) {                                                          \
        snprintf(load_error, sizeof load_error, "Python C API symbol %s missing", name); \
        return 0;                                                                    \
    }
    BIND(IsInitialized, "Py_IsInitialized")
    BIND(InitializeEx, "Py_InitializeEx")
    BIND(GILState_Ensure, "PyGILState_Ensure")
    BIND(GILState_Release, "PyGILState_Release")
    BIND(Eval_SaveThread, "PyEval_SaveThread")
    BIND(Import_ImportModule, "PyImport_ImportModule")
    BIND(Object_CallMethod, "PyObject_CallMethod")
    BIND(Long_AsLongLong, "PyLong_AsLongLong")
    BIND(DecRef, "Py_DecRef")
    BIND(Err_Occurred, "PyErr_Occurred")
    BIND(Err_Fetch, "PyErr_Fetch")
    BIND(Err_Clear, "PyErr_Clear")
    BIND(Object_Str, "PyObject_Str")
    BIND(Unicode_AsUTF8, "PyUnicode_AsUTF8")
    BIND(Sys_GetObject, "PySys_GetObject")
    BIND(List_Insert, "PyList_Insert")
    BIND(Unicode_FromString, "PyUnicode_FromString")
#undef BIND
    if (!py.IsInitialized()) {
        py.InitializeEx(0);           /* no signal handlers: the host owns them */
        py.Eval_SaveThread();         /* release the lock: every call takes it */
    }
    py.ready = 1;
    return 1;
}

/* the pending Python exception as text (cleared); the caller holds the lock */
static void python_error(char *buf, size_t n) {
    PyObj *type = NULL, *value = NULL, *tb = NULL;
    snprintf(buf, n, "Python error");
    if (py.Err_Occurred() == NULL) return;
    py.Err_Fetch(&type, &value, &tb);
    PyObj *s = py.Object_Str(value != NULL ? value : type);
    if (s != NULL) {
        const char *u = py.Unicode_AsUTF8(s);
        if (u != NULL) snprintf(buf, n, "%s", u);
        py.DecRef(s);
    }
    py.Err_Clear();
    if (type) py.DecRef(type);
    if (value) py.DecRef(value);
    if (tb) py.DecRef(tb);
}

/* the folder of a file:// resource location (percent escapes decoded) */
static void resource_path(const char *uri, char *out, size_t n) {
    const char *s = uri != NULL ? uri : "";
    size_t k = 0;
    if (strncmp(s, "file://", 7) == 0) s += 7;
    if (strncmp(s, "localhost/", 10) == 0) s += 9;
    while (*s && k + 1 < n) {
        if (s[0] == '%' && s[1] && s[2]) {
            char hex[3] = {s[1], s[2], 0};
            out[k++] = (char)strtol(hex, NULL, 16);
            s += 3;
        } else {
            out[k++] = *s++;
        }
    }
    out[k] = 0;
}

/* ---- instances ------------------------------------------------------------------------- */
typedef struct {
    long long handle;             /* the runtime's instance number */
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    char name[256];
} Instance;

static void say(fmi2CallbackLogger logger, fmi2ComponentEnvironment env, const char *name,
                fmi2Status status, const char *msg) {
    if (logger == NULL) return;
    logger(env, name, status, status == fmi2Warning ? "logStatusWarning" : "logStatusError",
           "%s", msg);
}

/* log the runtime's messages for this instance (the caller holds the lock) */
static void relay(Instance *inst, fmi2Status status) {
    PyObj *r = py.Object_CallMethod(runtime, "take_message", "L", inst->handle);
    char buf[4096];
    if (r == NULL) {
        python_error(buf, sizeof buf);
    } else {
        const char *u = py.Unicode_AsUTF8(r);
        snprintf(buf, sizeof buf, "%s", u != NULL ? u : "(no message)");
        py.DecRef(r);
    }
    if (buf[0]) say(inst->logger, inst->env, inst->name, status, buf);
}

/* the status a runtime call returned; a Python exception is an error, logged */
static fmi2Status finish(Instance *inst, PyObj *r) {
    fmi2Status status;
    if (r == NULL) {
        char buf[4096];
        python_error(buf, sizeof buf);
        say(inst->logger, inst->env, inst->name, fmi2Error, buf);
        return fmi2Error;
    }
    status = (fmi2Status)py.Long_AsLongLong(r);
    py.DecRef(r);
    if (status != fmi2OK) relay(inst, status);
    return status;
}

#define CALL(inst, ...)                                                              \
    do {                                                                             \
        int gil_ = py.GILState_Ensure();                                             \
        fmi2Status st_ = finish(inst, py.Object_CallMethod(runtime, __VA_ARGS__));   \
        py.GILState_Release(gil_);                                                   \
        return st_;                                                                  \
    } while (0)

FMI2_Export const char *fmi2GetTypesPlatform(void) { return "default"; }
FMI2_Export const char *fmi2GetVersion(void) { return "2.0"; }

FMI2_Export fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                                          fmi2String fmuGUID,
                                          fmi2String fmuResourceLocation,
                                          const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean loggingOn) {
    fmi2CallbackLogger logger = functions != NULL ? functions->logger : NULL;
    fmi2ComponentEnvironment env = functions != NULL ? functions->componentEnvironment : NULL;
    const char *name = instanceName != NULL ? instanceName : "";
    char buf[4096];
    (void)visible;
    (void)loggingOn;
    if (fmuType != fmi2CoSimulation) {
        say(logger, env, name, fmi2Error, "this FMU is co-simulation only");
        return NULL;
    }
    if (!bind_python()) {
        say(logger, env, name, fmi2Error, load_error);
        return NULL;
    }
    int gil = py.GILState_Ensure();
    if (runtime == NULL) {
        /* the resources folder first on sys.path: its bootstrap finds afo_mj */
        char dirbuf[4096];
        resource_path(fmuResourceLocation, dirbuf, sizeof dirbuf);
        PyObj *path = py.Sys_GetObject("path");
        PyObj *dir = py.Unicode_FromString(dirbuf);
        if (path != NULL && dir != NULL) py.List_Insert(path, 0, dir);
        if (dir != NULL) py.DecRef(dir);
        PyObj *boot = py.Import_ImportModule("afo_mj_fmu_bootstrap");
        if (boot != NULL) {
            runtime = py.Object_CallMethod(boot, "runtime", NULL);
            py.DecRef(boot);
        }
        if (runtime == NULL) {
            python_error(buf, sizeof buf);
            py.GILState_Release(gil);
            say(logger, env, name, fmi2Error, buf);
            return NULL;
        }
    }
    PyObj *r = py.Object_CallMethod(runtime, "instantiate", "sss", fmuResourceLocation, name,
                                    fmuGUID != NULL ? fmuGUID : "");
    long long handle = 0;
    if (r == NULL) {
        python_error(buf, sizeof buf);
    } else {
        handle = py.Long_AsLongLong(r);
        py.DecRef(r);
        if (handle <= 0) {
            PyObj *m = py.Object_CallMethod(runtime, "take_message", "L", 0LL);
            const char *u = m != NULL ? py.Unicode_AsUTF8(m) : NULL;
            snprintf(buf, sizeof buf, "%s", u != NULL ? u : "instantiation failed");
            if (m != NULL) py.DecRef(m);
            else py.Err_Clear();
        }
    }
    py.GILState_Release(gil);
    if (handle <= 0) {
        say(logger, env, name, fmi2Error, buf);
        return NULL;
    }
    Instance *inst = (Instance *)calloc(1, sizeof(Instance));
    if (inst == NULL) return NULL;
    inst->handle = handle;
    inst->logger = logger;
    inst->env = env;
    snprintf(inst->name, sizeof inst->name, "%s", name);
    return inst;
}

FMI2_Export void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL) return;
    int gil = py.GILState_Ensure();
    PyObj *r = py.Object_CallMethod(runtime, "free", "L", inst->handle);
    if (r != NULL) py.DecRef(r);
    else py.Err_Clear();
    py.GILState_Release(gil);
    free(inst);
}

FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn,
                                           size_t nCategories, const fmi2String categories[]) {
    (void)c;
    (void)loggingOn;
    (void)nCategories;
    (void)categories;
    return fmi2OK;                /* errors and warnings are always logged */
}

FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                                           fmi2Real tolerance, fmi2Real startTime,
                                           fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *inst = (Instance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    CALL(inst, "setup_experiment", "Ldid", inst->handle, startTime, (int)stopTimeDefined,
         stopTime);
}

FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    CALL(inst, "enter_initialization", "L", inst->handle);
}

FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    CALL(inst, "exit_initialization", "L", inst->handle);
}

FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *inst = (Instance *)c;
    CALL(inst, "terminate", "L", inst->handle);
}

FMI2_Export fmi2Status fmi2Reset(fmi2Component c) {
    Instance *inst = (Instance *)c;
    CALL(inst, "reset", "L", inst->handle);
}

FMI2_Export fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    CALL(inst, "get_real", "LKKK", inst->handle, (unsigned long long)(size_t)vr,
         (unsigned long long)nvr, (unsigned long long)(size_t)value);
}

FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    CALL(inst, "set_real", "LKKK", inst->handle, (unsigned long long)(size_t)vr,
         (unsigned long long)nvr, (unsigned long long)(size_t)value);
}

/* the FMU has Real variables only: any other type is an unknown value reference */
static fmi2Status no_variables(fmi2Component c, size_t nvr, const char *what) {
    Instance *inst = (Instance *)c;
    char buf[256];
    if (nvr == 0) return fmi2OK;
    snprintf(buf, sizeof buf, "%s: this FMU has no variables of that type (Real only)", what);
    say(inst->logger, inst->env, inst->name, fmi2Error, buf);
    return fmi2Error;
}

FMI2_Export fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t nvr, fmi2Integer value[]) {
    (void)vr;
    (void)value;
    return no_variables(c, nvr, "fmi2GetInteger");
}

FMI2_Export fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t nvr, fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    return no_variables(c, nvr, "fmi2GetBoolean");
}

FMI2_Export fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t nvr, fmi2String value[]) {
    (void)vr;
    (void)value;
    return no_variables(c, nvr, "fmi2GetString");
}

FMI2_Export fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t nvr, const fmi2Integer value[]) {
    (void)vr;
    (void)value;
    return no_variables(c, nvr, "fmi2SetInteger");
}

FMI2_Export fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t nvr, const fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    return no_variables(c, nvr, "fmi2SetBoolean");
}

FMI2_Export fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t nvr, const fmi2String value[]) {
    (void)vr;
    (void)value;
    return no_variables(c, nvr, "fmi2SetString");
}

static fmi2Status unsupported(fmi2Component c, const char *what) {
    Instance *inst = (Instance *)c;
    char buf[256];
    snprintf(buf, sizeof buf, "%s is not supported by this FMU (see its capability flags)",
             what);
    if (inst != NULL) say(inst->logger, inst->env, inst->name, fmi2Error, buf);
    return fmi2Error;
}

FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) {
    (void)s;
    return unsupported(c, "fmi2GetFMUstate");
}

FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
    (void)s;
    return unsupported(c, "fmi2SetFMUstate");
}

FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) {
    (void)s;
    return unsupported(c, "fmi2FreeFMUstate");
}

FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s,
                                                  size_t *size) {
    (void)s;
    (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}

FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s,
                                             fmi2Byte serializedState[], size_t size) {
    (void)s;
    (void)serializedState;
    (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}

FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c,
                                               const fmi2Byte serializedState[],
                                               size_t size, fmi2FMUstate *s) {
    (void)serializedState;
    (void)size;
    (void)s;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}

FMI2_Export fmi2Status fmi2GetDirectionalDerivative(
    fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
    const fmi2ValueReference vKnown_ref[], size_t nKnown, const fmi2Real dvKnown[],
    fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component c,
                                                   const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[],
                                                   const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    CALL(inst, "set_input_derivatives", "LKKKK", inst->handle, (unsigned long long)(size_t)vr,
         (unsigned long long)nvr, (unsigned long long)(size_t)order,
         (unsigned long long)(size_t)value);
}

FMI2_Export fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c,
                                                    const fmi2ValueReference vr[], size_t nvr,
                                                    const fmi2Integer order[],
                                                    fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                                  fmi2Real communicationStepSize,
                                  fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *inst = (Instance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    CALL(inst, "do_step", "Ldd", inst->handle, currentCommunicationPoint,
         communicationStepSize);
}

FMI2_Export fmi2Status fmi2CancelStep(fmi2Component c) {
    return unsupported(c, "fmi2CancelStep (doStep is synchronous)");
}

FMI2_Export fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s,
                                     fmi2Status *value) {
    (void)s;
    (void)value;
    return unsupported(c, "fmi2GetStatus (doStep is synchronous)");
}

FMI2_Export fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s,
                                         fmi2Real *value) {
    Instance *inst = (Instance *)c;
    if (s != fmi2LastSuccessfulTime) return unsupported(c, "fmi2GetRealStatus");
    int gil = py.GILState_Ensure();
    PyObj *r = py.Object_CallMethod(runtime, "last_time", "LK", inst->handle,
                                    (unsigned long long)(size_t)value);
    fmi2Status st = finish(inst, r);
    py.GILState_Release(gil);
    return st;
}

FMI2_Export fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s,
                                            fmi2Integer *value) {
    (void)s;
    (void)value;
    return unsupported(c, "fmi2GetIntegerStatus");
}

FMI2_Export fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s,
                                            fmi2Boolean *value) {
    (void)s;
    (void)value;
    return unsupported(c, "fmi2GetBooleanStatus");
}

FMI2_Export fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s,
                                           fmi2String *value) {
    (void)s;
    (void)value;
    return unsupported(c, "fmi2GetStringStatus");
}
