"""Running a study: the search driven over the evaluations (`runner`), the search problem of a
study (`problem`), the record of each evaluation and the ledger of a run (`record`), the results
file written as the run goes (`writer`), MPI ranks (`parallel`), the commands of the command
line (`commands`), a dynamic study's `wcs solve` (`dynamics`), and the study paired with its
evaluator that `wcs.load_study` returns (`evaluable`). The top layer below `wcs.cli`; the Python
API's `wcs.run(study)` is `runner.run`.
"""
