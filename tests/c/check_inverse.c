/* Runs the exported backlash inverse on a sequence read from stdin and prints x_d.
 *
 * Usage: check_inverse smooth|naive y0 [x0] < y_d values, one per line
 * "smooth" uses the header smooth.h (constant smooth_axis), "naive" naive.h
 * (constant naive_axis); with x0 the state starts from servoid_backlash_reset_at.
 * Output: one x_d per line, %.17g, so that it reads back as exactly the same double.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "naive.h"
#include "smooth.h"

int main(int argc, char **argv)
{
    const servoid_backlash_params *params;
    servoid_backlash_state state;
    double y0, y_d;

    if (argc < 3 || argc > 4) {
        fprintf(stderr, "usage: %s smooth|naive y0 [x0] < values\n", argv[0]);
        return 2;
    }
    params = strcmp(argv[1], "naive") == 0 ? &naive_axis : &smooth_axis;
    y0 = strtod(argv[2], NULL);
    if (argc == 4) {
        servoid_backlash_reset_at(params, &state, y0, strtod(argv[3], NULL));
    } else {
        servoid_backlash_reset(&state, y0);
    }
    while (scanf("%lf", &y_d) == 1) {
        printf("%.17g\n", servoid_backlash_inverse(params, &state, y_d));
    }
    /* the linear block is exported too: touch it so a wrong array size fails to compile */
    return smooth_axis_a[SMOOTH_AXIS_NA - 1] == 0.0 && smooth_axis_b[SMOOTH_AXIS_NB] == 0.0 ? 3 : 0;
}
