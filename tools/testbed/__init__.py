"""What tests and benchmarks drive the processes with, kept out of the robot's code: random
MPFC instances and the Gurobi reference solver, scripted robot motions for the estimator,
synthetic terrain maps for S3. Robot code never imports it."""
