"""pgx's chess and Gardner's minichess as two-player games of the deep engine, and its boards converted to and from
python-chess's."""
