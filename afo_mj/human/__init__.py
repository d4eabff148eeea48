"""The human side: anthropometry, the MuJoCo walker and the ankle test stand."""
