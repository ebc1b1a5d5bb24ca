/*
 * main.c - the servoid bench firmware as a host process on a pseudo-terminal.
 *
 *   servoid-bench-fw [options]        opens a pty, prints "port /dev/pts/N", serves it
 *   servoid-bench-fw --plant-only     reads one input per line on stdin, prints y (for tests)
 *   servoid-bench-fw --twin-only      the twin: one set point (rad) per line on stdin, one period
 *                                     each (--period-us), prints the drive's registers (for tests)
 *
 * The motor is the pseudo-Wiener model given by --a/--b/--delay/--m2/--c1/--c2
 * unless a twin is given (--twin-phys, --twin-fw: the arrays of
 * servoid.drivers.twin.TwinParams.pack(); --twin-output load|motor): then
 * the firmware's loop (../loop.c) runs at the twin's ticks.
 *
 * The main loop is what a board's main() would be (fw_init, then fw_poll
 * forever); it only adds a select() so the process sleeps while idle.
 * Options: see usage() below.
 */
#define _XOPEN_SOURCE 700
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/select.h>
#include <termios.h>
#include <unistd.h>
#ifdef __linux__
#include <sys/prctl.h>
#endif

#include "../firmware.h"
#include "hal_host.h"
#include "sim_motor.h"

static volatile sig_atomic_t stop;

static void on_signal(int sig)
{
    (void)sig;
    stop = 1;
}

static void usage(void)
{
    fputs(
        "usage: servoid-bench-fw [--a A1,A2,..] [--b B0,..] [--delay D] [--m2 M2] [--c1 C1] [--c2 C2]\n"
        "                        [--cpr COUNTS] [--noise STD] [--seed N] [--flip-tx P] [--flip-rx P]\n"
        "                        [--drop P] [--mute-after FRAMES] [--restart-after REQUESTS]\n"
        "                        [--clock-start US] [--boot-id HEX] [--trace FILE] [--link PATH]\n"
        "                        [--twin-phys P0,P1,.. --twin-fw F0,F1,.. --twin-output load|motor]\n"
        "       servoid-bench-fw --plant-only [model options] < inputs\n"
        "       servoid-bench-fw --twin-only --twin-phys .. --twin-fw .. --period-us US < set points\n",
        stderr);
}

static int parse_list(const char *text, double *out, int max)
{
    int n = 0;
    char *end;
    while (*text) {
        if (n == max) return -1;
        out[n++] = strtod(text, &end);
        if (end == text) return -1;
        text = end;
        if (*text == ',') text++;
        else if (*text) return -1;
    }
    return n;
}

static double number(const char *name, const char *text)
{
    char *end;
    double v = strtod(text, &end);
    if (end == text || *end) {
        fprintf(stderr, "servoid-bench-fw: %s=%s is not a number\n", name, text);
        exit(2);
    }
    return v;
}

static int open_pty(char *name, size_t cap, int *slave_fd)
{
    struct termios t;
    int master = posix_openpt(O_RDWR | O_NOCTTY);
    const char *path;
    if (master < 0 || grantpt(master) != 0 || unlockpt(master) != 0 || !(path = ptsname(master))) return -1;
    strncpy(name, path, cap - 1);
    name[cap - 1] = '\0';
    /* keep the slave open: with no slave fd left, reads of the master fail with EIO */
    *slave_fd = open(name, O_RDWR | O_NOCTTY);
    if (*slave_fd < 0 || tcgetattr(*slave_fd, &t) != 0) return -1;
    t.c_iflag &= (tcflag_t) ~(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON);
    t.c_oflag &= (tcflag_t)~OPOST;
    t.c_lflag &= (tcflag_t) ~(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
    t.c_cflag &= (tcflag_t) ~(CSIZE | PARENB);
    t.c_cflag |= CS8;
    if (tcsetattr(*slave_fd, TCSANOW, &t) != 0) return -1;
    fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
    return master;
}

static int twin_only(const double *phys, const double *fw, int output_load, uint64_t seed, double period_s)
{
    static twin_sim_t t;
    char line[128];
    twin_init(&t, phys, fw, output_load, seed);
    loop_enable(&t.loop, 1);
    /* servoid.drivers.twin.TwinPlant.step: the registers at the set point's arrival, then one period */
    while (fgets(line, sizeof line, stdin)) {
        const loop_t *l = &t.loop;
        printf("%.17g %.17g %.17g %.17g %.17g %.17g %.17g %d %d\n", l->cnt_m, l->cnt_l, l->vel, l->pos_est, l->cur,
               l->duty, l->sp, l->enabled, l->fault);
        if (l->enabled) loop_command(&t.loop, strtod(line, 0));
        twin_advance(&t, period_s);
    }
    return 0;
}

/* Remove the link made at start only if it still points to our port: never a path someone else put there. */
static void remove_own_link(const char *link, const char *port)
{
    char target[256];
    ssize_t n = readlink(link, target, sizeof target - 1);
    if (n < 0) return;
    target[n] = '\0';
    if (strcmp(target, port) == 0) unlink(link);
}

static int plant_only(const bl_model_t *model)
{
    bl_plant_t p;
    char line[128];
    bl_plant_init(&p, model);
    while (fgets(line, sizeof line, stdin)) printf("%.17g\n", bl_plant_step(&p, strtod(line, 0)));
    return 0;
}

int main(int argc, char **argv)
{
    /* MODEL_PLANT (servoid.drivers.model_plant) unless told otherwise */
    bl_model_t model = {2, 0, 1, {-0.8, 0.15}, {0.35}, 1.0, 0.02, 0.03};
    hal_host_config_t hc;
    static sim_motor_t motor;
    fw_state_t fw;
    double cpr = 65536.0, noise = 0.0; /* a 16-bit encoder on the output shaft */
    static double phys[TW_P_SIZE], fwc[TW_F_SIZE];
    int n_phys = 0, n_fw = 0, output_load = 1, only_twin = 0;
    double period_us = SM_DEFAULT_PERIOD_US;
    long restart_after = -1;
    int i, master, slave, only_plant = 0, restarted = 0;
    char port[128];
    const char *link = 0, *problem;

    memset(&hc, 0, sizeof hc);
    hc.mute_after = -1;
    for (i = 1; i < argc; i++) {
        const char *opt = argv[i], *val = i + 1 < argc ? argv[i + 1] : 0;
        if (!strcmp(opt, "--plant-only")) { only_plant = 1; continue; }
        if (!strcmp(opt, "--twin-only")) { only_twin = 1; continue; }
        if (!strcmp(opt, "--help")) { usage(); return 0; }
        if (!val) { usage(); return 2; }
        i++;
        if (!strcmp(opt, "--a")) {
            if ((model.na = parse_list(val, model.a, SM_MAX_NA)) < 1) { fputs("bad --a\n", stderr); return 2; }
        } else if (!strcmp(opt, "--b")) {
            int nb = parse_list(val, model.b, SM_MAX_NB + 1);
            if (nb < 1) { fputs("bad --b\n", stderr); return 2; }
            model.nb = nb - 1;
        } else if (!strcmp(opt, "--twin-phys")) {
            if ((n_phys = parse_list(val, phys, TW_P_SIZE)) != TW_P_SIZE) {
                fprintf(stderr, "servoid-bench-fw: --twin-phys needs %d numbers\n", TW_P_SIZE);
                return 2;
            }
        } else if (!strcmp(opt, "--twin-fw")) {
            if ((n_fw = parse_list(val, fwc, TW_F_SIZE)) != TW_F_SIZE) {
                fprintf(stderr, "servoid-bench-fw: --twin-fw needs %d numbers\n", TW_F_SIZE);
                return 2;
            }
        } else if (!strcmp(opt, "--twin-output")) {
            if (strcmp(val, "load") && strcmp(val, "motor")) { fputs("bad --twin-output\n", stderr); return 2; }
            output_load = !strcmp(val, "load");
        } else if (!strcmp(opt, "--period-us")) period_us = number(opt, val);
        else if (!strcmp(opt, "--delay")) model.delay = (int)number(opt, val);
        else if (!strcmp(opt, "--m2")) model.m2 = number(opt, val);
        else if (!strcmp(opt, "--c1")) model.c1 = number(opt, val);
        else if (!strcmp(opt, "--c2")) model.c2 = number(opt, val);
        else if (!strcmp(opt, "--cpr")) cpr = number(opt, val);
        else if (!strcmp(opt, "--noise")) noise = number(opt, val);
        else if (!strcmp(opt, "--seed")) hc.seed = (uint64_t)number(opt, val);
        else if (!strcmp(opt, "--flip-tx")) hc.flip_tx = number(opt, val);
        else if (!strcmp(opt, "--flip-rx")) hc.flip_rx = number(opt, val);
        else if (!strcmp(opt, "--drop")) hc.drop = number(opt, val);
        else if (!strcmp(opt, "--mute-after")) hc.mute_after = (long)number(opt, val);
        else if (!strcmp(opt, "--restart-after")) restart_after = (long)number(opt, val);
        else if (!strcmp(opt, "--clock-start")) hc.clock_start_us = (uint32_t)number(opt, val);
        else if (!strcmp(opt, "--boot-id")) hc.boot_id = (uint16_t)strtoul(val, 0, 16);
        else if (!strcmp(opt, "--link")) link = val;
        else if (!strcmp(opt, "--trace")) {
            if (!(hc.trace = fopen(val, "w"))) { perror(val); return 2; }
        } else {
            fprintf(stderr, "servoid-bench-fw: unknown option %s\n", opt);
            usage();
            return 2;
        }
    }
    if ((problem = bl_model_check(&model))) {
        fprintf(stderr, "servoid-bench-fw: %s\n", problem);
        return 2;
    }
    if ((n_phys != 0) != (n_fw != 0)) {
        fputs("servoid-bench-fw: a twin needs both --twin-phys and --twin-fw\n", stderr);
        return 2;
    }
    if (n_phys) {
        sim_motor_init_twin(&motor, phys, fwc, output_load, hc.seed + 1u);
        cpr = twin_output_cpr(&motor.twin);
        if (cpr != floor(cpr)) {
            fprintf(stderr, "servoid-bench-fw: the twin's output encoder has %.17g counts per turn, not a whole number\n", cpr);
            return 2;
        }
    }
    if (!(cpr >= 16.0 && cpr <= 16777216.0)) {
        fputs("servoid-bench-fw: --cpr must lie in 16..16777216\n", stderr);
        return 2;
    }
    if (only_plant) return plant_only(&model);
    if (only_twin) {
        if (!n_phys) { fputs("servoid-bench-fw: --twin-only needs a twin\n", stderr); return 2; }
        return twin_only(phys, fwc, output_load, hc.seed + 1u, period_us / 1e6);
    }

#ifdef __linux__
    prctl(PR_SET_PDEATHSIG, SIGTERM); /* never outlive the process that started us */
#endif
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    if ((master = open_pty(port, sizeof port, &slave)) < 0) {
        perror("servoid-bench-fw: cannot open a pseudo-terminal");
        return 1;
    }
    if (link && symlink(port, link) != 0) { /* never over an existing path: nothing is replaced */
        perror(link);
        return 1;
    }
    hc.fd = master;
    hc.counts_per_rev = (uint32_t)cpr;
    if (!n_phys) sim_motor_init(&motor, &model, cpr / 6.283185307179586, noise, hc.seed + 1u);
    hal_host_init(&hc, &motor);
    fw_init(&fw);
    printf("port %s\nboot %04x\n", link ? link : port, fw.boot);
    fflush(stdout);

    while (!stop) {
        fd_set rd;
        struct timeval tv;
        uint32_t wait = fw_idle_us(&fw);
        if (wait > 50000u) wait = 50000u; /* wake now and then to notice signals */
        FD_ZERO(&rd);
        FD_SET(master, &rd);
        tv.tv_sec = 0;
        tv.tv_usec = (suseconds_t)wait;
        if (select(master + 1, &rd, 0, 0, &tv) < 0 && errno != EINTR) break;
        fw_poll(&fw);
        if (restart_after >= 0 && !restarted && (long)fw.rx_ok >= restart_after) {
            restarted = 1;
            hal_host_reboot();
            fw_init(&fw);
        }
    }
    if (link) remove_own_link(link, port);
    fprintf(stderr, "servoid-bench-fw: stopped (frames in %lu, rejected %lu, out %lu)\n",
            (unsigned long)fw.rx_ok, (unsigned long)fw.rx_bad, (unsigned long)fw.tx);
    close(slave);
    close(master);
    return 0;
}
