"""What a run leaves and what is read from it: the results file as an xarray Dataset
(`dataset`), the evaluation store beside it (`store`), its extremes (`extremes`), the verdict
(`verdict`), its summary for the terminal (`summary`), what drives an extreme (`drivers`), the
mesh check (`meshcheck`), the comparison of two files (`compare`) and the ParaView files of a
solved scenario (`paraview`)."""
