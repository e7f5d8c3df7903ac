"""The central store: many robots' sites, of many buildings and floors, in one PostgreSQL database.

Each robot keeps working on its local site (SQLite stays the source of truth during a
pass); ``bomc sync`` pushes what is new to the central schema, ``bomc pull`` makes a local
site from it so another robot can run the next pass, a lease row keeps two robots off one
floor at once, and ``bomc evaluate`` / ``bomc view`` read a ``postgresql://`` site through
:mod:`bomc_bt.central.reader`. The schema and its versions: :mod:`bomc_bt.central.schema`
and ``docs/central-store.md``.

Modules: ``connection`` (where the database is, psycopg, errors), ``schema`` (DDL and
migrations), ``identity`` (a site's building / floor / robot, ``site.json``), ``rows``
(the graph's rows in SQLite and in PostgreSQL), ``site_files`` (the files that travel),
``sync`` and ``pull`` (the two directions), ``lease`` (one pass per floor), ``reader``
(the read adapter), ``params`` (the ``central:`` config section).
"""
