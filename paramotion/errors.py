"""Exceptions shared by the whole package.

``UserError`` is raised for bad input (files, arguments, parameters): the command line prints
its message as one line and exits with status 2, without a traceback.
"""


class UserError(Exception):
    """Bad input from the user: a one-line message naming the input and what is wrong."""


class ParameterError(UserError):
    """A ROS parameter value outside its declared type or range."""
