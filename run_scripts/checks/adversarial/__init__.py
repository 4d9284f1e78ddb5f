"""The adversarial sweep's harness, truths and cases; the entry point and its usage are
run_scripts/checks/adversarial_sweep.py."""
