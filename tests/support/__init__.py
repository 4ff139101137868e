"""Helpers the tests share: scenes and their solves (scenes), broken study files (bad_studies),
scikit-fem reference forms (reference_forms), analytic search problems (search_problems), the
fuzzer's mutants and runner (fuzz_mutants, fuzz_runner) and a headless-Chromium driver (cdp)."""
