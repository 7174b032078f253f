"""Tests of the most_likely algorithm, with hybridtrack's contract check."""

from hybridtrack_zigzag import MostLikely


def test_most_likely_honours_the_algorithm_contract(hybridtrack_contracts, hybridtrack_registry):
    assert hybridtrack_registry.get("algorithm", "most_likely") is MostLikely
    result = hybridtrack_contracts.check_algorithm(MostLikely)  # the check builds it with its example_parameters
    assert result.loglik.shape == (21, 2) and set(result.mode) <= {0, 1}
