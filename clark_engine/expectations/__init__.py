"""A mission's ``checks:`` and its safety, judged from what a run recorded.

One evaluator for dry runs, campaigns and real flights alike.
"""
