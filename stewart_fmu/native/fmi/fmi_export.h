/* Symbol visibility: the FMU's binary exports the fmi* functions and nothing else (built with
 * -fvisibility=hidden on GCC/Clang; on Windows only what is marked dllexport is exported). */
#ifndef STEWART_FMI_EXPORT_H
#define STEWART_FMI_EXPORT_H

#if defined(_WIN32) || defined(__CYGWIN__)
#define FMI_EXPORT __declspec(dllexport)
#elif defined(__GNUC__) || defined(__clang__)
#define FMI_EXPORT __attribute__((visibility("default")))
#else
#define FMI_EXPORT
#endif

#endif
