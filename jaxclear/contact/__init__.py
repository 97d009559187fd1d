"""Contact mechanics of a journal in its bearing: normal force laws and friction laws."""
