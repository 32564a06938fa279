from foldfab.cli import main

raise SystemExit(main())
