/* Test program (tests/test_export_c.py): two exported models linked into one program,
 * each run to its first output time after 0.1 s; prints each model's outputs there
 * as "NAME t v1 v2 ..." with %.17g. */
#include <stdio.h>

#include "four_bar.h"
#include "rsup.h"

int main(void)
{
    four_bar_sim *a = four_bar_create();
    rsup_sim *b = rsup_create();
    int k;
    if (a == NULL || b == NULL || four_bar_start(a, four_bar_t_end()) != 0
            || rsup_start(b, rsup_t_end()) != 0)
        return 2;
    /* interleaved, to show the instances share nothing */
    for (k = 1; k <= 100; k++)
        if (four_bar_step_to(a, k * four_bar_dt()) != 0 || rsup_step_to(b, k * rsup_dt()) != 0)
            return 3;
    printf("four_bar %.17g", four_bar_time(a));
    for (k = 0; k < four_bar_output_count(); k++)
        printf(" %.17g", four_bar_output(a, k));
    printf("\nrsup %.17g", rsup_time(b));
    for (k = 0; k < rsup_output_count(); k++)
        printf(" %.17g", rsup_output(b, k));
    printf("\n");
    four_bar_destroy(a);
    rsup_destroy(b);
    return 0;
}
