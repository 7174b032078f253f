"""What plugin authors build on: the bank-estimator base (:mod:`.estimation`), measurement assembly
(:mod:`.measurements`), the sensor network (:mod:`.network`), batched linear algebra (:mod:`.linalg`),
Wald thresholds (:mod:`.thresholds`), time stamps (:mod:`.timestamps`), clutter scans (:mod:`.scans`) and
process noise per second (:mod:`.process_noise`)."""
