"""The lab: offline work that imports the product and is never imported by it (synthetic data,
ray-traced ground truth, training, benchmarks, the module map); its commands are in ``cli.py``."""
