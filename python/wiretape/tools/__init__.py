"""The commands that read session files, one module each: ``show``,
``stats``, ``verify``, ``convert`` and ``diff`` (``wiretape show FILE``...).
"""
