/*
 * Executed-instruction counter for qemu-system-arm (TCG plugin API v1, QEMU 7.2).
 *
 * Debian's QEMU 7.2 loads plugins but ships no <qemu-plugin.h>, so the few API
 * v1 declarations this plugin uses are written out below, exactly as in QEMU
 * 7.2's include/qemu/qemu-plugin.h.
 *
 * Arguments: start=0xADDR,end=0xADDR (the two marker functions of the bench
 * image; their bodies differ so that LTO cannot fold them into one address).
 * Each time the start marker executes, counting begins; when the end marker
 * executes, one line is written to stderr:
 *     region <n> insns <count> vdiv <count> vsqrt <count>
 * counting the instructions executed in between (call overhead included; the
 * bench subtracts an empty region measured the same way).
 *
 * With profile=N also: after the line of a region of at least N instructions,
 * one line per instruction address executed in it,
 *     pc <hex address> <times>
 * and a line "end profile" (bench-m4/profile.py names the functions).
 */
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- QEMU 7.2 plugin API v1, declared here ---- */
typedef uint64_t qemu_plugin_id_t;
typedef struct qemu_info_t qemu_info_t; /* only passed through */
struct qemu_plugin_tb;
struct qemu_plugin_insn;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_CB_R_REGS, QEMU_PLUGIN_CB_RW_REGS };
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, qemu_plugin_vcpu_tb_trans_cb_t cb);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb, size_t idx);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *insn);
char *qemu_plugin_insn_disas(const struct qemu_plugin_insn *insn);
void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn, qemu_plugin_vcpu_udata_cb_t cb,
                                            enum qemu_plugin_cb_flags flags, void *userdata);
#define QEMU_PLUGIN_EXPORT __attribute__((visibility("default")))
QEMU_PLUGIN_EXPORT int qemu_plugin_version = 1;
/* ---- end of the API declarations ---- */

enum { KIND_PLAIN = 0, KIND_VDIV = 1, KIND_VSQRT = 2, KIND_START = 4, KIND_END = 8 };

static uint64_t start_addr, end_addr;
static bool counting;
static uint64_t n_insns, n_vdiv, n_vsqrt, n_region;

/* The profile (profile=N): per-address counts of the current region, the
 * addresses in the order first executed (to print and clear only those). */
#define PROFILE_SLOTS (1u << 20) /* halfword slots: 2 MiB of flash from 0x08000000 */
static const uint64_t profile_base = 0x08000000;
static uint64_t profile_threshold;
static uint32_t *profile_counts, *profile_touched;
static uint32_t n_touched;

static void profile_count(uint64_t pc) {
    uint64_t slot = (pc - profile_base) / 2;
    if (pc < profile_base || slot >= PROFILE_SLOTS) return;
    if (profile_counts[slot]++ == 0) profile_touched[n_touched++] = (uint32_t)slot;
}

static void profile_flush(bool print) {
    for (uint32_t i = 0; i < n_touched; i++) {
        uint32_t slot = profile_touched[i];
        if (print)
            fprintf(stderr, "pc %llx %u\n", (unsigned long long)(profile_base + 2ull * slot), profile_counts[slot]);
        profile_counts[slot] = 0;
    }
    if (print) fprintf(stderr, "end profile\n");
    n_touched = 0;
}

/* udata: the instruction's KIND_* bits, its address above them. */
#define KIND_BITS 4

static void on_insn(unsigned int vcpu, void *udata) {
    (void)vcpu;
    uintptr_t kind = (uintptr_t)udata & ((1u << KIND_BITS) - 1);
    if (kind & KIND_END) {
        if (counting) {
            fprintf(stderr, "region %llu insns %llu vdiv %llu vsqrt %llu\n", (unsigned long long)n_region,
                    (unsigned long long)n_insns, (unsigned long long)n_vdiv, (unsigned long long)n_vsqrt);
            if (profile_counts) profile_flush(n_insns >= profile_threshold);
            n_region++;
        }
        counting = false;
        return;
    }
    if (kind & KIND_START) {
        counting = true;
        n_insns = n_vdiv = n_vsqrt = 0;
        return;
    }
    if (counting) {
        n_insns++;
        if (kind & KIND_VDIV) n_vdiv++;
        if (kind & KIND_VSQRT) n_vsqrt++;
        if (profile_counts) profile_count((uint64_t)((uintptr_t)udata >> KIND_BITS));
    }
}

static void on_tb(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint64_t pc = qemu_plugin_insn_vaddr(insn);
        uintptr_t kind = KIND_PLAIN;
        if (pc == start_addr) kind |= KIND_START;
        if (pc == end_addr) kind |= KIND_END;
        char *dis = qemu_plugin_insn_disas(insn);
        if (dis) {
            if (strstr(dis, "vdiv")) kind |= KIND_VDIV;
            if (strstr(dis, "vsqrt")) kind |= KIND_VSQRT;
            free(dis);
        }
        uintptr_t data = kind | ((uintptr_t)pc << KIND_BITS);
        qemu_plugin_register_vcpu_insn_exec_cb(insn, on_insn, QEMU_PLUGIN_CB_NO_REGS, (void *)data);
    }
}

QEMU_PLUGIN_EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc, char **argv) {
    (void)info;
    for (int i = 0; i < argc; i++) {
        if (strncmp(argv[i], "start=", 6) == 0) start_addr = strtoull(argv[i] + 6, NULL, 0);
        if (strncmp(argv[i], "end=", 4) == 0) end_addr = strtoull(argv[i] + 4, NULL, 0);
        if (strncmp(argv[i], "profile=", 8) == 0) {
            profile_threshold = strtoull(argv[i] + 8, NULL, 0);
            profile_counts = calloc(PROFILE_SLOTS, sizeof *profile_counts);
            profile_touched = calloc(PROFILE_SLOTS, sizeof *profile_touched);
            if (!profile_counts || !profile_touched) {
                fprintf(stderr, "insn_count: no memory for the profile\n");
                return -1;
            }
        }
    }
    if (start_addr == 0 || end_addr == 0 || start_addr == end_addr) {
        fprintf(stderr, "insn_count: need distinct start=0x.. and end=0x.. marker addresses\n");
        return -1;
    }
    /* Thumb: the symbol value has bit 0 set; the instruction address does not. */
    start_addr &= ~(uint64_t)1;
    end_addr &= ~(uint64_t)1;
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_tb);
    return 0;
}
