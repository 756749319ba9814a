"""Impact laws: the Delassus matrix and eq. 11 (delassus), the impact-model ladder (laws), NNLS."""
