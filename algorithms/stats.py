"""Summary statistics shared by the adjustment, matching, DEM and accuracy steps."""

import numpy as np

#: a normal distribution's sigma over its median absolute deviation (NMAD = NMAD_SCALE x MAD)
NMAD_SCALE = 1.4826


def statistics_table(values):
    """{name: (n, min, mean, max, RMS, sigma)} of each array in `values` (the columns of Kornus et al. 2006,
    Table 3)."""
    table = {}
    for key, v in values.items():
        v = np.asarray(v, float)
        v = v[np.isfinite(v)]
        table[key] = (
            v.size,
            *(
                (
                    float(v.min()),
                    float(v.mean()),
                    float(v.max()),
                    float(np.sqrt(np.mean(v * v))),
                    float(v.std(ddof=1)) if v.size > 1 else float("nan"),
                )
                if v.size
                else (float("nan"),) * 5
            ),
        )
    return table
