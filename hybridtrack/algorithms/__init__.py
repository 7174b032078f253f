"""The algorithms, each one implementation on the engine's bank: built only from the public kernel API and components looked up in the registry.

Nothing here knows a particular plugin; every component is reached through
the interfaces of :mod:`hybridtrack.core.interfaces`, so a third-party estimator or
detector that implements them works here exactly as a built-in does.

* :mod:`.known_switch` — seed 001 Algorithm 1 (SPRT on a bank re-created at each known switch);
* :mod:`.unknown_change` — seed 000 Algorithm 3 repeated (change at an unknown time, growing or bounded bank);
* :mod:`.bank_runs` — what the banks share: the batch of one, the R runs of an SPRT bank checked, grouped and recorded;
* :mod:`.mode_sets` — the turn bank of seed 001 and the check that modes share one layout;
* :mod:`.multiple_model` — IMM, GPB1 and GPB2 with Markov switching (mode probabilities in log space);
* :mod:`.algorithm4` — Wald's expected sample sizes and the bank size of seed 000 Algorithm 4;
* :mod:`.known_modes` — the filter told the true schedule (the "optimal KF" of seed 001).
"""
