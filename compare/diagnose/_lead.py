"""Whether one candidate's held-out lead over another is real: their held-out losses compared sample by sample.

Two candidates that both explain a mismatch are two non-nested models,
both wrong in some part (the model's own error, parameters the updating
could not reach). Which is closer to the recording is Vuong's question
(Vuong 1989, Econometrica 57: 307-333): the sum of the pointwise
differences of their losses, against its own spread. Here the loss is
each sample's held-out chi2 (``Problem.held_out_loss``), the residual is
autocorrelated, so the spread is the long-run variance of the differences
summed over batches of one fold block of each kind, with Newey and West's
Bartlett weights and bandwidth rule (1994, Rev. Econ. Stud. 61: 631-653),
and the statistic is read against Student's t with one degree of freedom
fewer than the batches, one-sided at the null test's quantile. A lead
that one stretch of the record gives and the rest does not is not
consistent; a lead the whole record gives, however small its share of
the chi2, is.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from ._hypotheses import BLOCK_S, NULL_QUANTILE

__all__ = ["lead_test", "LEAD_BATCH_S"]

# One block of each fold: every batch holds held-out samples of both fits.
LEAD_BATCH_S = 2 * BLOCK_S


def lead_test(time, loss_lead, loss_rival, quantile=NULL_QUANTILE):
    """Whether ``loss_lead`` is lower than ``loss_rival`` consistently over the record.

    Parameters
    ----------
    time : ndarray (n,)
        Sample times (s).
    loss_lead, loss_rival : ndarray (n,)
        Each sample's held-out chi2 under the two candidates.
    quantile : float
        One-sided level of the test.

    Returns
    -------
    dict
        ``lead`` (the rival's summed loss minus the lead's), ``t`` (the lead
        over its long-run standard deviation), ``critical`` (Student's t
        quantile), ``batches``, ``bandwidth`` (Newey-West lags) and
        ``consistent`` (``t`` beyond ``critical``).
    """
    time = np.asarray(time, float)
    d = np.asarray(loss_rival, float) - np.asarray(loss_lead, float)
    batch = np.floor((time - time[0]) / LEAD_BATCH_S + 1e-9).astype(int)
    sums = np.bincount(batch, d)
    nb = sums.size
    lead = float(d.sum())
    if nb < 3:
        return {"lead": lead, "t": 0.0, "critical": math.inf, "batches": nb, "bandwidth": 0, "consistent": False}
    lags = int(math.floor(4.0 * (nb / 100.0) ** (2.0 / 9.0)))
    c = sums - sums.mean()
    lrv = float(c @ c) / nb + 2.0 * sum((1.0 - j / (lags + 1.0)) * float(c[j:] @ c[:-j]) / nb
                                        for j in range(1, lags + 1))
    if lrv > 0:
        t = lead / math.sqrt(nb * lrv)
    else:
        t = math.inf if lead > 0 else 0.0
    critical = float(stats.t.ppf(quantile, nb - 1))
    return {"lead": lead, "t": float(t), "critical": critical, "batches": nb, "bandwidth": lags,
            "consistent": bool(t > critical)}
