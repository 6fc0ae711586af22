/* A minimal FMI 2.0 / 3.0 co-simulation master for the native FMU's tests and benchmark.
 *
 *   fmi_master run   2|3 BINARY TOKEN SCRIPT          print the outputs after every step
 *   fmi_master bench 2|3 BINARY TOKEN SCRIPT REPEAT    time set + doStep + get, print us/step (CPU time)
 *
 * SCRIPT (text): "n h", "n_in n_vin vr...", "n_out n_vout vr...", then n rows of n_in input
 * values: n_vin value references holding n_in values (more than n_vin for FMI 3.0 arrays, their
 * elements in row-major order; equal for FMI 2.0), the same for the outputs. The master
 * instantiates, initializes at t = 0, and for k < n sets the row's inputs, steps from k h by h
 * and gets the outputs. Output lines: "k status v1 v2 ..." with %.17g.
 *
 * It builds for Windows too (x86_64-w64-mingw32-gcc -D__USE_MINGW_ANSI_STDIO=1: mingw's own
 * printf and scanf), loading the DLL with LoadLibrary. mingw-w64's scanf rounds a few 17-digit
 * decimals to the neighbouring double, so scripts for both carry hexadecimal floats (C99 %lf
 * reads them exactly). */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _WIN32
#include <windows.h>
#define dlopen(path, flags) ((void *)LoadLibraryA(path))
#define dlsym(lib, name) ((void *)GetProcAddress((HMODULE)(lib), name))
#define dlclose(lib) FreeLibrary((HMODULE)(lib))
#define dlerror() "LoadLibrary failed"
#else
#include <dlfcn.h>
#endif

#include "fmi2_api.h"
#include "fmi3_api.h"

static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    (void)env;
    fprintf(stderr, "[%s %d %s] %s\n", name, (int)status, category, message);
}

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    fprintf(stderr, "[%d %s] %s\n", (int)status, category, message);
}

static void *sym(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return f;
}

static double now(void) {
#ifdef _WIN32
    LARGE_INTEGER count, freq;
    QueryPerformanceCounter(&count);
    QueryPerformanceFrequency(&freq);
    return (double)count.QuadPart / (double)freq.QuadPart;
#else
    struct timespec ts;  /* this thread's CPU time: on a loaded machine, time spent preempted is not counted */
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
#endif
}

int main(int argc, char **argv) {
    int bench, version, n, nin, nout, nvin, nvout, k, j, rep, repeat = 1, status = 0;
    double h, *in, *out, t0;
    unsigned *vin, *vout;
    void *lib;
    FILE *f;
    if (argc < 6) {
        fprintf(stderr, "usage: fmi_master run|bench 2|3 BINARY TOKEN SCRIPT [REPEAT]\n");
        return 2;
    }
    bench = strcmp(argv[1], "bench") == 0;
    version = atoi(argv[2]);
    if (bench && argc > 6) repeat = atoi(argv[6]);
    f = fopen(argv[5], "r");
    if (!f || fscanf(f, "%d %lf", &n, &h) != 2) return 2;
    if (fscanf(f, "%d %d", &nin, &nvin) != 2) return 2;
    vin = malloc(sizeof *vin * (nvin + 1));
    for (j = 0; j < nvin; j++)
        if (fscanf(f, "%u", &vin[j]) != 1) return 2;
    if (fscanf(f, "%d %d", &nout, &nvout) != 2) return 2;
    vout = malloc(sizeof *vout * (nvout + 1));
    out = malloc(sizeof *out * (nout + 1));
    for (j = 0; j < nvout; j++)
        if (fscanf(f, "%u", &vout[j]) != 1) return 2;
    in = malloc(sizeof *in * ((size_t)n * nin + 1));
    for (k = 0; k < n * nin; k++)
        if (fscanf(f, "%lf", &in[k]) != 1) return 2;
    fclose(f);
    lib = dlopen(argv[3], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    for (rep = 0; rep < repeat; rep++) {
        if (version == 2) {
            fmi2CallbackFunctions cb = {logger2, calloc, free, NULL, NULL};
            fmi2Component (*inst)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                  fmi2Boolean, fmi2Boolean) = (fmi2Component(*)(fmi2String, fmi2Type, fmi2String,
                                  fmi2String, const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean))sym(lib, "fmi2Instantiate");
            fmi2Status (*setup)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real) =
                (fmi2Status(*)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real))sym(lib, "fmi2SetupExperiment");
            fmi2Status (*enter)(fmi2Component) = (fmi2Status(*)(fmi2Component))sym(lib, "fmi2EnterInitializationMode");
            fmi2Status (*exit_)(fmi2Component) = (fmi2Status(*)(fmi2Component))sym(lib, "fmi2ExitInitializationMode");
            fmi2Status (*setr)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2Real *) =
                (fmi2Status(*)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2Real *))sym(lib, "fmi2SetReal");
            fmi2Status (*getr)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Real *) =
                (fmi2Status(*)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Real *))sym(lib, "fmi2GetReal");
            fmi2Status (*step)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean) =
                (fmi2Status(*)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean))sym(lib, "fmi2DoStep");
            fmi2Status (*term)(fmi2Component) = (fmi2Status(*)(fmi2Component))sym(lib, "fmi2Terminate");
            void (*freei)(fmi2Component) = (void (*)(fmi2Component))sym(lib, "fmi2FreeInstance");
            fmi2Component c = inst("master", fmi2CoSimulation, argv[4], "", &cb, 0, 0);
            if (!c || setup(c, 0, 0.0, 0.0, 0, 0.0) || enter(c) || exit_(c)) return 3;
            t0 = now();
            for (k = 0; k < n; k++) {
                status = setr(c, vin, nin, in + (size_t)k * nin);
                if (!status) status = step(c, k * h, h, 1);
                if (!status) status = getr(c, vout, nout, out);
                if (!bench) {
                    printf("%d %d", k, status);
                    for (j = 0; j < nout; j++) printf(" %.17g", out[j]);
                    printf("\n");
                }
                if (status) break;
            }
            if (bench) printf("%.6f us/step\n", 1e6 * (now() - t0) / n);
            term(c);
            freei(c);
        } else {
            fmi3Instance (*inst)(fmi3String, fmi3String, fmi3String, fmi3Boolean, fmi3Boolean, fmi3Boolean, fmi3Boolean,
                                 const fmi3ValueReference *, size_t, fmi3InstanceEnvironment, fmi3LogMessageCallback,
                                 fmi3IntermediateUpdateCallback) =
                (fmi3Instance(*)(fmi3String, fmi3String, fmi3String, fmi3Boolean, fmi3Boolean, fmi3Boolean, fmi3Boolean,
                                 const fmi3ValueReference *, size_t, fmi3InstanceEnvironment, fmi3LogMessageCallback,
                                 fmi3IntermediateUpdateCallback))sym(lib, "fmi3InstantiateCoSimulation");
            fmi3Status (*enter)(fmi3Instance, fmi3Boolean, fmi3Float64, fmi3Float64, fmi3Boolean, fmi3Float64) =
                (fmi3Status(*)(fmi3Instance, fmi3Boolean, fmi3Float64, fmi3Float64, fmi3Boolean, fmi3Float64))sym(lib, "fmi3EnterInitializationMode");
            fmi3Status (*exit_)(fmi3Instance) = (fmi3Status(*)(fmi3Instance))sym(lib, "fmi3ExitInitializationMode");
            fmi3Status (*setr)(fmi3Instance, const fmi3ValueReference *, size_t, const fmi3Float64 *, size_t) =
                (fmi3Status(*)(fmi3Instance, const fmi3ValueReference *, size_t, const fmi3Float64 *, size_t))sym(lib, "fmi3SetFloat64");
            fmi3Status (*getr)(fmi3Instance, const fmi3ValueReference *, size_t, fmi3Float64 *, size_t) =
                (fmi3Status(*)(fmi3Instance, const fmi3ValueReference *, size_t, fmi3Float64 *, size_t))sym(lib, "fmi3GetFloat64");
            fmi3Status (*step)(fmi3Instance, fmi3Float64, fmi3Float64, fmi3Boolean, fmi3Boolean *, fmi3Boolean *,
                               fmi3Boolean *, fmi3Float64 *) =
                (fmi3Status(*)(fmi3Instance, fmi3Float64, fmi3Float64, fmi3Boolean, fmi3Boolean *, fmi3Boolean *,
                               fmi3Boolean *, fmi3Float64 *))sym(lib, "fmi3DoStep");
            fmi3Status (*term)(fmi3Instance) = (fmi3Status(*)(fmi3Instance))sym(lib, "fmi3Terminate");
            void (*freei)(fmi3Instance) = (void (*)(fmi3Instance))sym(lib, "fmi3FreeInstance");
            fmi3Boolean ev, te, er;
            fmi3Float64 last;
            fmi3Instance c = inst("master", argv[4], "", 0, 0, 0, 0, NULL, 0, NULL, logger3, NULL);
            if (!c || enter(c, 0, 0.0, 0.0, 0, 0.0) || exit_(c)) return 3;
            t0 = now();
            for (k = 0; k < n; k++) {
                status = setr(c, vin, nvin, in + (size_t)k * nin, nin);
                if (!status) status = step(c, k * h, h, 1, &ev, &te, &er, &last);
                if (!status) status = getr(c, vout, nvout, out, nout);
                if (!bench) {
                    printf("%d %d", k, status);
                    for (j = 0; j < nout; j++) printf(" %.17g", out[j]);
                    printf("\n");
                }
                if (status) break;
            }
            if (bench) printf("%.6f us/step\n", 1e6 * (now() - t0) / n);
            term(c);
            freei(c);
        }
    }
    dlclose(lib);
    free(in), free(out), free(vin), free(vout);
    return status ? 4 : 0;
}
