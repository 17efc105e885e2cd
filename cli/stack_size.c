/* Thread stacks of the mimic program: at least 1 MiB for every thread that
 * asks for less. This is a process-wide policy, so the program owns it, not
 * a library (DESIGN.md, Layering); it is linked into the mimic executable
 * only.
 *
 * Why: mimic serve runs on civetweb, whose worker threads Debian's build
 * (libcivetweb 1.15) starts with a fixed 100 KiB stack: its
 * CIVETWEB_THREAD_STACK_SIZE / USE_STACK_SIZE is a compile-time setting,
 * with no option or API to change it at run time. glibc (2.36) carves the
 * static TLS of every loaded library out of each thread's stack, and mimic
 * loads OpenBLAS (60 KiB of TLS) and METIS (29 KiB) through CHOLMOD, which
 * leaves a civetweb worker about 10 KiB: it overflows on its first request.
 * Neither library's TLS can be shed (they come with Debian's CHOLMOD).
 *
 * How: the executable defines pthread_attr_setstacksize, which the dynamic
 * linker then binds for every shared library (civetweb's call included),
 * and forwards to glibc's with the size raised. A thread that asks for
 * 1 MiB or more, or sets no size (glibc's default: the stack rlimit,
 * usually 8 MiB), is unaffected. A program embedding serve/ must do the
 * same, or use a civetweb built with larger stacks (serve/mim_serve.h). */
#include <dlfcn.h> /* RTLD_NEXT: _GNU_SOURCE comes from the build */
#include <pthread.h>
#include <stddef.h>

#define MIN_STACK ((size_t)1 << 20)

typedef int (*setstacksize_fn)(pthread_attr_t *, size_t);
static setstacksize_fn real_setstacksize;
static pthread_once_t real_once = PTHREAD_ONCE_INIT;

static void find_real(void)
{
    *(void **)&real_setstacksize = dlsym(RTLD_NEXT, "pthread_attr_setstacksize");
}

int pthread_attr_setstacksize(pthread_attr_t *attr, size_t size)
{
    pthread_once(&real_once, find_real);
    return real_setstacksize(attr, size < MIN_STACK ? MIN_STACK : size);
}
