"""The footopt command line (argparse only; library code never reads sys.argv)."""
