/*
 * insnwin: a QEMU TCG plugin that counts executed guest instructions in marked windows.
 *
 * Debian's QEMU 7.2 ships neither plugins nor qemu-plugin.h, so the few v1 API functions used
 * here are declared by hand (they are stable in QEMU 4.2 .. 9.x).
 *
 * Arguments (comma separated after the .so path):
 *   start=0xADDR        first instruction of the window-start marker function
 *   end=0xADDR          first instruction of the window-end marker function
 *   sel=NAME@0xADDR     a selector function: executing it makes NAME the current window
 *   grp=NAME@0xLO-0xHI  attribute instructions at addresses LO <= pc < HI to group NAME
 *                       (repeat for more ranges of the same group; at most 4 groups)
 *
 * Every executed instruction adds 1 to a counter (inline, no callback). When `start` executes
 * the counter is remembered; when `end` executes the difference is added to the current
 * window's statistics (count, sum, min, max). A window therefore holds the instructions from
 * the first instruction of the start marker up to, not including, the first instruction of the
 * end marker. Instructions inside a group's ranges are also summed per window and group. At
 * exit one line per window is printed to stderr:
 *   insnwin NAME n=<windows> sum=<instructions> min=<..> max=<..> [GROUP=<instructions> ...]
 *
 * Build: gcc -shared -fPIC -O2 -fvisibility=hidden -o libinsnwin.so insnwin.c
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
typedef struct qemu_info_t qemu_info_t;
typedef void (*tb_cb)(qemu_plugin_id_t, struct qemu_plugin_tb *);
typedef void (*vcpu_cb)(unsigned int, void *);
typedef void (*exit_cb)(qemu_plugin_id_t, void *);

void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t, tb_cb);
void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *, vcpu_cb,
                                            int /* QEMU_PLUGIN_CB_NO_REGS */, void *);
void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *,
                                                int /* QEMU_PLUGIN_INLINE_ADD_U64 */, void *,
                                                uint64_t);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *, size_t);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t, exit_cb, void *);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

#define MAX_WINDOWS 16
#define MAX_GROUPS 4
#define MAX_RANGES 256

struct window {
    char name[48];
    uint64_t pc;
    uint64_t n, sum, min, max;
    uint64_t group_sum[MAX_GROUPS];
};

struct range {
    uint64_t lo, hi;
    int group;
};

static char group_names[MAX_GROUPS][48];
static uint64_t group_insns[MAX_GROUPS], group_t0[MAX_GROUPS];
static int n_groups;
static struct range ranges[MAX_RANGES];
static int n_ranges;

static struct window windows[MAX_WINDOWS];
static int n_windows;
static int current = -1;
static uint64_t insns, t0, start_pc, end_pc;
static int open_window;

static void on_start(unsigned int vcpu, void *u)
{
    t0 = insns;
    for (int g = 0; g < n_groups; g++) {
        group_t0[g] = group_insns[g];
    }
    open_window = 1;
}

static void on_end(unsigned int vcpu, void *u)
{
    if (!open_window || current < 0) {
        return;
    }
    open_window = 0;
    uint64_t d = insns - t0;
    struct window *w = &windows[current];
    if (w->n == 0 || d < w->min) {
        w->min = d;
    }
    if (d > w->max) {
        w->max = d;
    }
    w->n++;
    w->sum += d;
    for (int g = 0; g < n_groups; g++) {
        w->group_sum[g] += group_insns[g] - group_t0[g];
    }
}

static void on_select(unsigned int vcpu, void *u)
{
    current = (int)(intptr_t)u;
    open_window = 0;
}

static void on_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    size_t n = qemu_plugin_tb_n_insns(tb);
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *in = qemu_plugin_tb_get_insn(tb, i);
        uint64_t pc = qemu_plugin_insn_vaddr(in);
        if (pc == start_pc) {
            qemu_plugin_register_vcpu_insn_exec_cb(in, on_start, 0, NULL);
        }
        if (pc == end_pc) {
            qemu_plugin_register_vcpu_insn_exec_cb(in, on_end, 0, NULL);
        }
        for (int k = 0; k < n_windows; k++) {
            if (pc == windows[k].pc) {
                qemu_plugin_register_vcpu_insn_exec_cb(in, on_select, 0, (void *)(intptr_t)k);
            }
        }
        qemu_plugin_register_vcpu_insn_exec_inline(in, 0, &insns, 1);
        for (int r = 0; r < n_ranges; r++) {
            if (pc >= ranges[r].lo && pc < ranges[r].hi) {
                qemu_plugin_register_vcpu_insn_exec_inline(in, 0, &group_insns[ranges[r].group], 1);
                break;
            }
        }
    }
}

static void at_exit(qemu_plugin_id_t id, void *u)
{
    for (int k = 0; k < n_windows; k++) {
        struct window *w = &windows[k];
        fprintf(stderr, "insnwin %s n=%llu sum=%llu min=%llu max=%llu", w->name,
                (unsigned long long)w->n, (unsigned long long)w->sum,
                (unsigned long long)w->min, (unsigned long long)w->max);
        for (int g = 0; g < n_groups; g++) {
            fprintf(stderr, " %s=%llu", group_names[g], (unsigned long long)w->group_sum[g]);
        }
        fprintf(stderr, "\n");
    }
    fprintf(stderr, "insnwin total n=1 sum=%llu min=%llu max=%llu\n", (unsigned long long)insns,
            (unsigned long long)insns, (unsigned long long)insns);
}

__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id,
                                                               const qemu_info_t *info, int argc,
                                                               char **argv)
{
    for (int i = 0; i < argc; i++) {
        if (!strncmp(argv[i], "start=", 6)) {
            start_pc = strtoull(argv[i] + 6, NULL, 0) & ~1ULL;
        } else if (!strncmp(argv[i], "end=", 4)) {
            end_pc = strtoull(argv[i] + 4, NULL, 0) & ~1ULL;
        } else if (!strncmp(argv[i], "sel=", 4)) {
            const char *at = strchr(argv[i] + 4, '@');
            size_t len = at ? (size_t)(at - (argv[i] + 4)) : 0;
            if (!at || len == 0 || len >= sizeof windows[0].name || n_windows == MAX_WINDOWS) {
                fprintf(stderr, "insnwin: bad argument %s\n", argv[i]);
                return -1;
            }
            memcpy(windows[n_windows].name, argv[i] + 4, len);
            windows[n_windows].pc = strtoull(at + 1, NULL, 0) & ~1ULL;
            n_windows++;
        } else if (!strncmp(argv[i], "grp=", 4)) {
            const char *at = strchr(argv[i] + 4, '@');
            size_t len = at ? (size_t)(at - (argv[i] + 4)) : 0;
            char *dash = NULL;
            if (!at || len == 0 || len >= sizeof group_names[0] || n_ranges == MAX_RANGES) {
                fprintf(stderr, "insnwin: bad argument %s\n", argv[i]);
                return -1;
            }
            int g = 0;
            while (g < n_groups && (strlen(group_names[g]) != len ||
                                    strncmp(group_names[g], argv[i] + 4, len))) {
                g++;
            }
            if (g == n_groups) {
                if (n_groups == MAX_GROUPS) {
                    fprintf(stderr, "insnwin: too many groups\n");
                    return -1;
                }
                memcpy(group_names[g], argv[i] + 4, len);
                n_groups++;
            }
            ranges[n_ranges].lo = strtoull(at + 1, &dash, 0) & ~1ULL;
            if (!dash || *dash != '-') {
                fprintf(stderr, "insnwin: bad range %s\n", argv[i]);
                return -1;
            }
            ranges[n_ranges].hi = strtoull(dash + 1, NULL, 0);
            ranges[n_ranges].group = g;
            n_ranges++;
        } else {
            fprintf(stderr, "insnwin: unknown argument %s\n", argv[i]);
            return -1;
        }
    }
    if (!start_pc || !end_pc) {
        fprintf(stderr, "insnwin: start= and end= are required\n");
        return -1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_trans);
    qemu_plugin_register_atexit_cb(id, at_exit, NULL);
    return 0;
}
