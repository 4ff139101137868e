"""Running a study: the search driven over the evaluations (`runner`), the search problem of a
study (`problem`), the record of each evaluation and the ledger of a run (`record`), the results
file written as the run goes (`writer`), MPI ranks (`parallel`), the commands of the command
line (`commands`), and the study paired with its evaluator that `wcs.load_study` returns
(`evaluable`). The top layer below `wcs.cli`.

`wcs.run` is this package and, as the contract has it (study-format.md §3), the call
`wcs.run(study)`: a name can be only one attribute of `wcs`, so the package is callable.
"""
import sys
import types


class _Run(types.ModuleType):
    def __call__(self, study, output=None, resume=False, progress=None, **kwargs):
        """The whole worst-scenario study -> xarray.Dataset (the results file's content); see `runner.run`."""
        from .runner import run
        return run(study, output=output, resume=resume, progress=progress, **kwargs)


sys.modules[__name__].__class__ = _Run
